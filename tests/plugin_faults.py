"""Faulty plugins for tests/test_plugins.py: classes that fail their protocol at load time or inside a run."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

from fusion import BaseEstimatorParams, Verdict
from matcher import MatchResult


class FailingParams(BaseModel):
    """how: what the matcher does at scan `at`: raise, or return something that is not a MatchResult."""

    model_config = ConfigDict(extra="forbid")
    how: Literal["raise", "none"] = "raise"
    at: int = 3


class FailingMatcher:
    """Reports a failed match for every scan until scan `at`, where it breaks its protocol."""

    Params = FailingParams

    def __init__(self, params: FailingParams) -> None:
        self.params, self.calls = params, 0

    def register(self, scan) -> MatchResult | None:
        """A failure until scan `at`; then raise or return None."""
        self.calls += 1
        if self.calls < self.params.at:
            return MatchResult.failure("this matcher never matches", n_points=len(scan.points))
        if self.params.how == "raise":
            raise RuntimeError(f"boom at scan {self.calls}")
        return None


class FailingEstimatorParams(BaseEstimatorParams):
    """how: what the estimator does at its `at`-th input of that kind: raise in add_match, return no Verdict
    from add_fix, or raise when built."""

    how: Literal["add_match", "add_fix", "init"] = "add_match"
    at: int = 3


class FailingEstimator:
    """Trusts every fix and never knows its pose; breaks its protocol as its params say."""

    Params = FailingEstimatorParams

    def __init__(self, params: FailingEstimatorParams, monitor) -> None:
        if params.how == "init":
            raise ValueError("cannot start")
        self.params, self.monitor, self.matches, self.fixes = params, monitor, 0, 0

    @property
    def pose(self) -> np.ndarray:
        """Never known."""
        return np.full((4, 4), np.nan)

    @property
    def cov(self) -> np.ndarray:
        """Never known."""
        return np.full((3, 3), np.inf)

    def add_match(self, stamp: float, result: MatchResult) -> None:
        """Raise at match `at` when told to."""
        self.matches += 1
        if self.params.how == "add_match" and self.matches == self.params.at:
            raise ZeroDivisionError("bad match")

    def add_fix(self, fix) -> Verdict | str:
        """A trusting verdict, or at fix `at` a string when told to."""
        self.fixes += 1
        if self.params.how == "add_fix" and self.fixes == self.params.at:
            return "trusted"
        return Verdict(True, math.nan, "trusts every fix")


class NoRegister:
    """A matcher without its method."""

    Params = FailingParams


class HalfEstimator:
    """An estimator without add_match and cov."""

    Params = FailingEstimatorParams

    def add_fix(self, fix) -> Verdict:
        """Trust it."""
        return Verdict(True, 0.0, "")

    pose = np.eye(4)


class NoParams:
    """A monitor without its parameter model."""

    def check(self, obs, ctx) -> Verdict:
        """Trust it."""
        return Verdict(True, 0.0, "")

    def commit(self, obs, verdict) -> None:
        """Nothing to keep."""

    def reset(self) -> None:
        """Nothing to forget."""

    def note_outage(self, stamp: float) -> None:
        """Nothing to note."""


class PlainParamsEstimator(FailingEstimator):
    """An estimator whose Params does not take what every estimator is given."""

    Params = FailingParams


not_a_class = 42
