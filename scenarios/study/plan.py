"""What the study measures and where: the charles_river library scenario with every matcher, and how its route is sampled
so the whole report fits a few minutes on 2 cores (GNSS over every epoch, matchers on bursts of consecutive revolutions
spaced along the route, one matcher chained over every third revolution for the heading drift)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from scenarios.spec import library
from scenarios.spec import overrides as overrides_
from scenarios.spec.scenario import Scenario
from scenarios.study.setups import FIELD_METHOD1_ID

SCENARIO = "charles_river"
"""The library scenario the study measures (the field study's route, BU Bridge to Charlestown Bridge)."""
MATCHERS = ("pcl6d", "bev3dof", "kiss_icp", "gicp")
"""Every built-in matcher, at its defaults: pcl6d is the study's Method 1, bev3dof its Method 2."""


@dataclass(frozen=True)
class StudyPlan:
    """How the route is sampled (each field's default chosen for the 15-minute budget on 2 cores, see docs/guide.md)."""

    burst_spacing_s: float = 10.0
    """A burst of consecutive revolutions starts every this many seconds along the stretch."""
    burst_scans: int = 3
    """Revolutions per burst: the first is a fresh matcher's reference, each later one a match (the last with a motion prior)."""
    pcl6d_every: int = 2
    """pcl6d (the slowest matcher) registers every this-many-th burst only."""
    chain_stride: int = 3
    """The chained odometry registers every this-many-th revolution: 3 chains at 3.3 Hz, within the 1-8 Hz the field
    study's Method 1 ran at. The chain is nearly all of the study's time (whole route, 1 in 2: 1,856 of 2,000 CPU
    seconds, kiss_icp and the LiDAR about 147 ms a chained revolution), so 1 in 2 took 16 min on 2 cores and 1 in 3 fits
    the 15. It changes finding h's figure little: over 1650-1850 m kiss_icp's chain ends 0.85 deg off at 3, 0.84 at 2
    and 1.34 at 1 (every revolution; seed 0)."""
    chain_segments: int = 4
    """The chained odometry is computed in this many consecutive pieces (in parallel), composed end to end."""
    chain_adequate_success: float = 0.95
    """The chained matcher is the fastest (by the bench's nominal cost) whose burst success is at least this."""
    post_outage_fixes: int = 10
    """Finding b: the first this-many measured fixes after each outage."""
    workers: int = 2
    """Processes."""

    def __post_init__(self) -> None:
        if not (
            self.burst_spacing_s > 0 and self.burst_scans >= 2 and min(self.pcl6d_every, self.chain_stride, self.chain_segments, self.workers) >= 1
        ):
            raise ValueError("study plan: need burst_spacing_s > 0, burst_scans >= 2 and pcl6d_every, chain_stride, chain_segments, workers >= 1")

    def as_dict(self) -> dict:
        return asdict(self)


def study_scenario(
    seed: int | None = None,
    stretch_m: tuple[float, float] | None = None,
    receiver: dict | None = None,
    field_method1: dict | None = None,
    overrides: list[str] | None = None,
) -> Scenario:
    """charles_river from the library with every matcher and no estimator (the study measures sensors and matchers);
    its expectations, which judge estimators, are left out. stretch_m: (start, end) route stations, default the whole route;
    receiver: [gnss] fields written over the library's (a setup's receiver, scenarios.study.setups); field_method1: pcl6d
    parameters of the field study's Method 1, added as the matcher setups.FIELD_METHOD1_ID; overrides: `--set key=value`
    assignments on that scenario (the conditions the study runs under: the vessel's waves, the LiDAR's foliage echoes, a
    matcher's parameter), written before a setup's receiver, which wins on the fields it names."""
    data = library.read(SCENARIO)
    data = {k: v for k, v in data.items() if k not in ("expect", "fast", "matchers", "estimators")}
    data["matchers"] = [{"id": m, "kind": m} for m in MATCHERS]
    if field_method1 is not None:
        data["matchers"].append({"id": FIELD_METHOD1_ID, "kind": "pcl6d", "params": dict(field_method1)})
    data = overrides_.apply(data, check_overrides(overrides or []))
    if receiver:
        data["gnss"] = {**data.get("gnss", {}), **receiver}
    data["estimators"] = []
    if seed is not None:
        data["seed"] = seed
    if stretch_m is not None:
        data["stretch"] = {"start_m": float(stretch_m[0]), "end_m": float(stretch_m[1])}
    return library.validate(data, f"{SCENARIO}.toml")


OWN_OPTIONS = {
    "seed": "give --seed instead",
    "stretch": "give --stretch instead",
    "estimators": "give --scenario FILE for estimators of your own",
    "expect": "the study judges the findings, not a scenario's expectations",
    "goals": "the study judges the findings, not a scenario's goals",
    "fast": "the study runs the route or --stretch",
    "world": "the study is the charles_river route's",
}
"""Keys of the study's scenario a `--set` may not write (those its own options set, those it leaves out, the world the
findings are about), each with what to do instead; the matchers only by id (`matchers.gicp.params.voxel_m`), never the
list the findings are measured with."""


def check_overrides(assignments: list[str]) -> list[str]:
    """The study's `--set` assignments, a ValueError naming one that writes a key the study sets itself or leaves out."""
    for text in assignments:
        key = text.partition("=")[0].strip()
        top = key.split(".")[0]
        if top in OWN_OPTIONS:
            raise ValueError(f"--set {text!r}: the study sets {top!r} itself; {OWN_OPTIONS[top]}")
        if key == "matchers":
            raise ValueError(
                f"--set {text!r}: the study runs its own matchers; set one's parameters by its id, e.g. matchers.gicp.params.voxel_m=0.4"
            )
    return assignments


def component_scenario(
    seed: int | None, stretch_m: tuple[float, float] | None, receiver: dict, commands: list, overrides: list[str] | None = None
) -> Scenario:
    """The study's scenario (its stretch, seed and a setup's [gnss] fields) with the command components `commands`
    ((section, scenarios.spec.command.CommandSpec) pairs) as its only matchers and estimators: what
    scenarios.study.components runs them in."""
    data = study_scenario(seed, stretch_m, receiver=receiver, overrides=overrides).resolved()
    data["matchers"] = [spec.model_dump(exclude_none=True) for section, spec in commands if section == "matchers"]
    data["estimators"] = [spec.model_dump(exclude_none=True) for section, spec in commands if section == "estimators"]
    return library.validate(data, f"{SCENARIO}.toml")


def parse_stretch(text: str) -> tuple[float, float]:
    """'START:END' route stations in metres (ValueError naming the problem)."""
    parts = text.split(":")
    try:
        start, end = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--stretch {text!r}: give START:END, route stations in metres, e.g. 1650:1800") from None
    if not (np.isfinite(start) and np.isfinite(end) and 0.0 <= start < end):
        raise ValueError(f"--stretch {text!r}: need 0 <= START < END")
    return start, end


def burst_starts(t_start: float, t_end: float, revolution_s: float, plan: StudyPlan) -> np.ndarray:
    """Start times of the bursts: every burst_spacing_s from t_start, each whole burst inside the stretch."""
    last = t_end - plan.burst_scans * revolution_s
    if last < t_start:
        return np.zeros(0)
    return t_start + np.arange(int(np.floor((last - t_start) / plan.burst_spacing_s + 1e-9)) + 1) * plan.burst_spacing_s


def chain_pieces(n_scans: int, segments: int) -> list[tuple[int, int]]:
    """(first, last) scan indices of each piece of the chain; consecutive pieces share their boundary scan."""
    cuts = np.unique(np.linspace(0, n_scans - 1, max(1, segments) + 1).round().astype(int))
    return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:])] if len(cuts) > 1 else []
