"""Expectations: `metric op value` over a dotted path of metrics.json, e.g. "estimators.ekf.ape.p95 < 6", or against
another metric with an offset, e.g. "estimators.ekf.ape.p95 <= estimators.gps_only.ape.p95 + 0.1"."""

from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass

from scenarios.score import units

OPERATORS = {"<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne, "<": operator.lt, ">": operator.gt}
_SYNTAX = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_.\-]*)\s*(<=|>=|==|!=|<|>)\s*(\S+)\s*$")
_AGAINST = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_.\-]*)\s*(<=|>=|==|!=|<|>)\s*([A-Za-z_][A-Za-z0-9_.\-]*)\s*(?:([+-])\s*(\S+))?\s*$")
TOP_LEVEL = ("run", "gps", "vessel", "estimators", "matchers")


@dataclass(frozen=True)
class Expectation:
    """One check on a run's metrics."""

    path: str
    op: str
    value: float
    """The bound, or with `ref` the offset added to that metric's value."""
    ref: str = ""
    """Another metric's dotted path the bound is taken from ('' : the bound is `value`)."""

    @property
    def text(self) -> str:
        if self.ref:
            sign = "-" if self.value < 0 else "+"
            return f"{self.path} {self.op} {self.ref} {sign} {abs(self.value):g}"
        return f"{self.path} {self.op} {self.value:g}"

    @classmethod
    def parse(cls, text: str, ids: dict[str, set[str]] | None = None) -> Expectation:
        """Parse 'path op number'; with `ids` (estimators / matchers -> ids) the path's owner must exist."""
        against = _AGAINST.match(str(text))
        match = _SYNTAX.match(str(text))
        ref = ""
        if against and not _is_number(against.group(3)):
            path, op, ref, sign, raw = against.groups()
            raw = raw if raw is not None else "0"
        elif match:
            path, op, raw = match.groups()
            sign = "+"
        else:
            raise ValueError(f"expectation {text!r}: write 'metric op number' or 'metric op metric + number', e.g. 'estimators.ekf.ape.p95 < 6.0'")
        try:
            value = float(raw) * (-1.0 if sign == "-" else 1.0)
        except ValueError:
            raise ValueError(f"expectation {text!r}: {raw!r} is not a number") from None
        for metric in (path, ref) if ref else (path,):
            _check_path(text, metric, ids)
        return cls(path, op, value, ref)

    def bound(self, ref_value: float = math.nan) -> float:
        """The value the metric is compared with: `value`, or the referenced metric's value plus `value`."""
        return ref_value + self.value if self.ref else self.value

    def holds(self, value: float, ref_value: float = math.nan) -> bool:
        """Whether a value meets this check (NaN never does, nor a NaN referenced metric)."""
        bound = self.bound(ref_value)
        return not (math.isnan(value) or math.isnan(bound)) and bool(OPERATORS[self.op](value, bound))

    def check(self, metrics: dict) -> Outcome:
        """Evaluate against a metrics dict; a missing or non-numeric metric (or referenced metric) fails with the reason."""
        actual, why = _lookup(metrics, self.path)
        if why:
            return Outcome(self, actual, False, why)
        ref_value = math.nan
        if self.ref:
            ref_value, why = _lookup(metrics, self.ref)
            if why:
                return Outcome(self, actual, False, why)
        passed = self.holds(actual, ref_value)
        bound = (
            f"{self.bound(ref_value):.4g} ({self.ref} {ref_value:.4g} {'-' if self.value < 0 else '+'} {abs(self.value):g})"
            if self.ref
            else f"{self.value:g}"
        )
        return Outcome(self, actual, passed, "" if passed else f"{self.path} = {actual:.4g}, expected {self.op} {bound}")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _check_path(text: str, path: str, ids: dict[str, set[str]] | None) -> None:
    """A metric path starts with a top-level family, is one metrics.json can hold a number at (every number there has a
    unit pattern, scenarios.score.units), and, with `ids`, names an estimator or matcher that exists. A goal keeps its
    ids unchecked (a variant may drop what it names), but a metric no run writes is a typo, never a goal to miss."""
    head = path.split(".")
    if head[0] not in TOP_LEVEL:
        raise ValueError(f"expectation {text!r}: metrics start with one of {', '.join(TOP_LEVEL)}")
    if units.quantity_of(path) is None:
        raise ValueError(f"expectation {text!r}: {path!r} is no metric a run writes (metrics.json's `units` block lists their patterns)")
    if ids is not None and head[0] in ids:
        if len(head) < 3:
            raise ValueError(f"expectation {text!r}: name a metric of {head[0]}.<id>, e.g. {head[0]}.<id>.ape.p95")
        if head[1] not in ids[head[0]]:
            raise ValueError(f"expectation {text!r}: no {head[0][:-1]} with id {head[1]!r} (have {', '.join(sorted(ids[head[0]])) or 'none'})")


def _lookup(metrics: dict, path: str) -> tuple[float, str]:
    """The number at a dotted path, or NaN and why it is not there (missing, not a number, NaN, or a command component
    that failed: none of its numbers passes a check, not even the costs it left under `external`)."""
    node = metrics
    for i, key in enumerate(path.split(".")):
        if i == 1 and isinstance(node, dict) and key not in node and path.split(".")[0] in ("estimators", "matchers"):
            return math.nan, f"no {path.split('.')[0][:-1]} {key!r} in this run (nothing to measure)"
        if i == 2 and isinstance(node, dict) and node.get("failed") is True and "reason" in node:
            return math.nan, f"{'.'.join(path.split('.')[:2])} failed: {node['reason']}"
        if not isinstance(node, dict) or key not in node:
            where = ".".join(path.split(".")[:i]) or "metrics"
            options = ", ".join(sorted(node)) if isinstance(node, dict) else "not a table"
            return math.nan, f"no metric {key!r} in {where} (has: {options})"
        node = node[key]
    if node is None:
        return math.nan, f"{path} is NaN (nothing to measure)"
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        return math.nan, f"{path} is not a number"
    actual = float(node)
    if math.isnan(actual):
        return actual, f"{path} is NaN (nothing to measure)"
    return actual, ""


@dataclass(frozen=True)
class Outcome:
    """An expectation's result: the metric's value, pass or fail, and why it failed."""

    expectation: Expectation
    actual: float
    passed: bool
    reason: str = ""

    def as_dict(self) -> dict:
        return {"expect": self.expectation.text, "value": self.actual, "pass": self.passed, "reason": self.reason}

    @property
    def applicable(self) -> bool:
        """False when the run had nothing to measure (the metric is null, e.g. a recall without any faulty fix)."""
        return "nothing to measure" not in self.reason

    def as_goal(self) -> dict:
        """A goal's record in metrics.json: met, not met, or null where the run had nothing to measure (a goal never
        fails the run)."""
        return {"goal": self.expectation.text, "value": self.actual, "met": self.passed if self.applicable else None, "reason": self.reason}
