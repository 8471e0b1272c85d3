"""Expectations: `metric op value` over a dotted path of metrics.json, e.g. "estimators.ekf.ape.p95 < 6"."""

from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass

OPERATORS = {"<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne, "<": operator.lt, ">": operator.gt}
_SYNTAX = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_.\-]*)\s*(<=|>=|==|!=|<|>)\s*(\S+)\s*$")
TOP_LEVEL = ("run", "gps", "vessel", "estimators", "matchers")


@dataclass(frozen=True)
class Expectation:
    """One check on a run's metrics."""

    path: str
    op: str
    value: float

    @property
    def text(self) -> str:
        return f"{self.path} {self.op} {self.value:g}"

    @classmethod
    def parse(cls, text: str, ids: dict[str, set[str]] | None = None) -> Expectation:
        """Parse 'path op number'; with `ids` (estimators / matchers -> ids) the path's owner must exist."""
        match = _SYNTAX.match(str(text))
        if not match:
            raise ValueError(f"expectation {text!r}: write 'metric op number', e.g. 'estimators.ekf.ape.p95 < 6.0'")
        path, op, raw = match.groups()
        try:
            value = float(raw)
        except ValueError:
            raise ValueError(f"expectation {text!r}: {raw!r} is not a number") from None
        head = path.split(".")
        if head[0] not in TOP_LEVEL:
            raise ValueError(f"expectation {text!r}: metrics start with one of {', '.join(TOP_LEVEL)}")
        if ids is not None and head[0] in ids:
            if len(head) < 3:
                raise ValueError(f"expectation {text!r}: name a metric of {head[0]}.<id>, e.g. {head[0]}.<id>.ape.p95")
            if head[1] not in ids[head[0]]:
                raise ValueError(f"expectation {text!r}: no {head[0][:-1]} with id {head[1]!r} (have {', '.join(sorted(ids[head[0]])) or 'none'})")
        return cls(path, op, value)

    def check(self, metrics: dict) -> Outcome:
        """Evaluate against a metrics dict; a missing or non-numeric metric fails with the reason."""
        node = metrics
        for i, key in enumerate(self.path.split(".")):
            if not isinstance(node, dict) or key not in node:
                where = ".".join(self.path.split(".")[:i]) or "metrics"
                options = ", ".join(sorted(node)) if isinstance(node, dict) else "not a table"
                return Outcome(self, math.nan, False, f"no metric {key!r} in {where} (has: {options})")
            node = node[key]
        if isinstance(node, bool) or not isinstance(node, (int, float)):
            return Outcome(self, math.nan, False, f"{self.path} is not a number")
        actual = float(node)
        if math.isnan(actual):
            return Outcome(self, actual, False, f"{self.path} is NaN (nothing to measure)")
        passed = bool(OPERATORS[self.op](actual, self.value))
        return Outcome(self, actual, passed, "" if passed else f"{self.path} = {actual:.4g}, expected {self.op} {self.value:g}")


@dataclass(frozen=True)
class Outcome:
    """An expectation's result: the metric's value, pass or fail, and why it failed."""

    expectation: Expectation
    actual: float
    passed: bool
    reason: str = ""

    def as_dict(self) -> dict:
        return {"expect": self.expectation.text, "value": self.actual, "pass": self.passed, "reason": self.reason}
