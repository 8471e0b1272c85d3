"""A user's own matchers and estimators of `kind = "command"` (scenarios.spec.command) in the study: run on a recording
of the study's stretch and scored in the findings they apply to, beside the built-ins, each with its own verdict.

Which findings a command component applies to (APPLIES; the others cannot use what its trajectory file holds):
- a command matcher: e (its rate, precision and unresolved share beside Method 1 and Method 2), f (its success against
  the points per scan) and h (its odometry's heading drift against the compass). Not g: the outlier shares are
  diagnostics a matcher reports from inside (MatchResult.info), and a trajectory file carries none. Not a-d: they judge
  the receiver.
- a command estimator: b (its error after each outage, against the receiver's open-water p95) and d (its error in open
  water). Not a and c: they judge the receiver itself (its outages, its HDOP), which an estimator's output does not
  change. Not e-h: they judge scan matching.
- a command matcher that reads no scans (recording = "nmea") applies to none, nor an estimator that reads no fixes
  (recording = "kitti": the KITTI layout holds no GNSS).

How: the study's scenario (its stretch, seed and each setup's receiver) with the command components alone is run by
scenarios.run into the study directory's components/<setup>/: the recording is written once into the cache (or found
there), the command runs, its trajectory is read back under its contract and scored as in any run (metrics.json there:
APE, coverage, the command's own costs). A matcher's scans are those of the first setup (the setups differ only in the
receiver); an estimator runs under each setup, since its fixes differ. From that run directory the study takes each
scan's pose (laid onto the scans as `riverbench score` lays it), the points of each revolution (counted as the run
streams them) and the exact relative motion, and measures the finding as for the built-ins:
- a command matcher's registration is a step from the previous scan with a pose to the next; `ok` is its own claim, a
  pose (as a built-in's ok is its own verdict); its error is against the exact relative motion of the LiDAR between the
  two scans; its rate is its poses over its whole run's wall time (start-up included: a command is one process over the
  whole recording, so its time per scan, and how it follows the points, is not measured);
- h: its poses laid onto the truth at its first pose (the built-in chain's start), whatever its declared anchor: a fit
  to the whole truth (se2, se3) would split the drift between the ends;
- b and d: its horizontal error at each receiver epoch (the pose of the scan at or before it) in place of the receiver's.
A component's verdict says whether the study's finding holds for it (for b: it too carries a wrong estimate after an
outage, which a fusion filter aims to beat); the built-ins' verdicts are untouched by it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from matcher.motion import pose_to_xyzrpy
from scenarios.pipeline import rescore
from scenarios.pipeline.external import FOLDER, one_file
from scenarios.score import metrics
from scenarios.score import windows as win
from scenarios.score.record import MatcherTrack
from scenarios.spec import library
from scenarios.spec.command import CommandSpec
from scenarios.spec.scenario import Scenario
from scenarios.study import gnss_findings, matcher_findings
from scenarios.study.findings import FINDINGS, Finding
from scenarios.study.tasks import ChainPiece, GnssSample
from scenarios.study.verdicts import Check, _f, _holds, checks_b, checks_d, checks_f, checks_h, headline, verdict

APPLIES = {"matchers": ("e", "f", "h"), "estimators": ("b", "d")}
"""The findings a command matcher and a command estimator apply to."""
WHY_NOT = {
    "a": "it judges the receiver's own outages under each bridge, which no component's output changes",
    "b": "it judges a position filter's error after an outage (a command estimator)",
    "c": "it judges the receiver's HDOP, which no component's output changes",
    "d": "it judges a position's error in open water (a command estimator)",
    "e": "it judges scan matchers (a command matcher)",
    "f": "it judges scan matchers (a command matcher)",
    "g": "its outlier shares are diagnostics a matcher reports from inside, and a trajectory file carries none",
    "h": "it judges a scan matcher's odometry (a command matcher)",
}
"""Why a finding takes no command component of the other kind (or none at all), for the one-line error."""
NO_SCANS = ("nmea",)
"""Recordings without the LiDAR's scans: a command matcher reading one matches nothing."""
NO_FIXES = ("kitti",)
"""Recordings without the receiver's fixes: a command estimator reading one is judged on no fix the study knows."""
ACCURATE_M = 0.05
"""f, reported beside a command matcher's success (its own claim: a pose): the share of its steps within this of the exact
relative motion (m) and within ACCURATE_DEG in yaw, since a command that never declares a failure succeeds on every scan."""
ACCURATE_DEG = 0.5
"""See ACCURATE_M."""


@dataclass(frozen=True)
class Component:
    """A command component taken into the study: its section ('matchers' or 'estimators') and its spec."""

    section: str
    spec: CommandSpec

    @property
    def id(self) -> str:
        return self.spec.id

    @property
    def findings(self) -> tuple[str, ...]:
        """The findings it applies to (none for a matcher without scans or an estimator without fixes)."""
        blind = NO_SCANS if self.section == "matchers" else NO_FIXES
        return () if self.spec.recording in blind else APPLIES[self.section]


def from_scenario(path: str | Path, reserved: tuple[str, ...], keys: tuple[str, ...] | None = None) -> list[Component]:
    """The command components of the scenario file `path` (validated as any scenario, but a section it leaves out is
    empty, not the default stack; only its command components are taken: the study's scenario stays its own).
    `reserved`: ids the study's own matchers have. `keys`: the findings asked
    for (None: every one a component applies to). One line (ValueError) when the file has no command component, an id is
    the study's, a component applies to no finding, or a finding asked for takes none of them."""
    data = library.read(path)
    for section in ("matchers", "estimators"):
        data.setdefault(section, [])  # not the default stack: its estimators would ask for a gicp the file need not have
    scenario = library.validate(data, Path(path).name)
    found = [Component(section, spec) for section, spec in scenario.commands]
    if not found:
        raise ValueError(f'--scenario {path}: no command component (a [[matchers]] or [[estimators]] of kind = "command") to study')
    for c in found:
        if c.id in reserved:
            raise ValueError(f"--scenario {path}: {c.section}.{c.id}: the study has a matcher of that id; rename it")
        if not c.findings:
            what = "scans (the LiDAR)" if c.section == "matchers" else "fixes (the receiver)"
            raise ValueError(
                f"--scenario {path}: {c.section}.{c.id} reads recording = {c.spec.recording!r}, which holds no {what}: no finding can use it"
            )
    for key in keys or ():
        if not any(key in c.findings for c in found):
            names = ", ".join(f"{c.section}.{c.id} ({', '.join(c.findings)})" for c in found)
            raise ValueError(f"--findings {key}: finding {key} cannot use a command component: {WHY_NOT[key]}; yours apply to: {names}")
    return found


def parse_findings(text: str) -> tuple[str, ...]:
    """`--findings e,f,h`: finding keys (ValueError naming an unknown one)."""
    keys = tuple(k.strip() for k in text.split(",") if k.strip())
    known = [f.key for f in FINDINGS]
    for key in keys:
        if key not in known:
            raise ValueError(f"--findings {text!r}: unknown finding {key!r}; give some of {', '.join(known)}")
    if not keys:
        raise ValueError(f"--findings {text!r}: give finding keys, e.g. e,f,h")
    return keys


class PointCounter:
    """A run observer (scenarios.pipeline.observer) counting each revolution's returns as the run streams it."""

    def __init__(self) -> None:
        self.points: dict[float, int] = {}

    def begin(self, stack, run_dir) -> None:
        pass

    def scan(self, event, truth, estimates) -> None:
        self.points[float(event.stamp)] = len(event.scan.points)

    def fix(self, fix, verdicts) -> None:
        pass

    def close(self, keep: bool) -> None:
        pass


@dataclass
class Scored:
    """A command component's run under one setup: its run directory, the node metrics.json gives it, its poses laid onto
    the run's scans (NaN: none) with the scan times and the points of each revolution."""

    run_dir: Path
    node: dict
    scan_t: np.ndarray
    placed: np.ndarray
    points: np.ndarray
    mount: np.ndarray


def scored(run_dir: Path, scenario: Scenario, tree: dict, component: Component, points: dict[float, int]) -> Scored:
    """Read back what the run scored for `component` (its poses on the run's scans under its contract)."""
    node = tree[component.section][component.id]
    run = rescore.FinishedRun.read(run_dir, scenario, tree)
    counts = on_scans(points, run.scan_t)
    placed = np.full((len(run.scan_t), 4, 4), np.nan)
    if not node.get("failed"):
        workdir = run_dir / FOLDER / component.id
        times = str(one_file(workdir, component.spec.times, "times")) if component.spec.times is not None else None
        _, placed = rescore.laid(run, run_dir / node["external"]["output"], component.spec.contract(times))
    return Scored(run_dir, node, run.scan_t, placed, counts, run.mount)


def on_scans(points: dict[float, int], scan_t: np.ndarray) -> np.ndarray:
    """The counted points of each scan (the count stamped nearest it within a microsecond: the run directory's stamps
    are read back from its files; 0 where none was counted)."""
    stamps = np.array(sorted(points), dtype=float)
    out = np.zeros(len(scan_t))
    if not len(stamps):
        return out
    j = np.clip(np.searchsorted(stamps, scan_t), 1, len(stamps) - 1) if len(stamps) > 1 else np.zeros(len(scan_t), int)
    j = np.where(np.abs(stamps[j - 1] - scan_t) < np.abs(stamps[j] - scan_t), j - 1, j) if len(stamps) > 1 else j
    near = np.abs(stamps[j] - scan_t) <= 1e-6
    out[near] = [points[float(stamps[k])] for k in j[near]]
    return out


def summary(s: Scored) -> dict:
    """What study.json keeps of a component's run: whether it failed and why, its coverage, APE and costs."""
    n = s.node
    out = {"failed": bool(n.get("failed")), "external": n.get("external", {})}
    if n.get("failed"):
        return out | {"reason": n.get("reason", "")}
    keep = ("coverage", "ape", "ape_aligned", "success") if "ape_aligned" in n else ("coverage", "ape", "available")
    return out | {k: n[k] for k in keep if k in n}


def matcher_rows(s: Scored, mid: str, trajectory) -> list[dict]:
    """The command matcher's steps as the study's burst rows (scenarios.study.tasks._row's fields): a row per scan after
    the first, a step from the previous scan with a pose; seconds and cpu_seconds its run's per pose."""
    ext = s.node.get("external", {})
    poses = max(int(ext.get("poses", 0) or 0), 1)
    per_wall, per_cpu = float(ext.get("wall_s", math.nan)) / poses, float(ext.get("cpu_s", math.nan)) / poses
    lidar = s.placed @ s.mount
    have = np.isfinite(s.placed).all(axis=(1, 2))
    rows, ref = [], None
    for i, t in enumerate(s.scan_t):
        if i > 0:
            err_m = err_deg = math.nan
            ok = bool(have[i] and ref is not None)
            if ok:
                truth = np.linalg.solve(trajectory.lidar_pose(float(s.scan_t[ref])), trajectory.lidar_pose(float(t)))
                delta = np.linalg.solve(truth, np.linalg.solve(lidar[ref], lidar[i]))
                err_m = float(np.linalg.norm(delta[:3, 3]))
                err_deg = float(abs(math.degrees(pose_to_xyzrpy(delta)[5])))
            rows.append(
                {
                    "matcher": mid,
                    "t": float(t),
                    "ok": ok,
                    "gated": False,
                    "points": int(s.points[i]),
                    "seconds": per_wall,
                    "cpu_seconds": per_cpu,
                    "error_m": err_m,
                    "yaw_error_deg": err_deg,
                }
            )
        if have[i]:
            ref = i
    return rows


def rate(rows: list[dict], s: Scored) -> dict:
    """Finding e for a command matcher: the fields of matcher_findings.rates, its rate from its whole run."""
    c = matcher_findings.columns(rows, rows[0]["matcher"] if rows else "")
    ext = s.node.get("external", {})
    poses = int(ext.get("poses", 0) or 0)
    wall, cpu = float(ext.get("wall_s", math.nan)), float(ext.get("cpu_s", math.nan))
    ok = c["ok"] == 1
    return {
        "registrations": int(len(c["t"])),
        "hz": poses / wall if poses and wall > 0 else math.nan,
        "ms_median": 1e3 * wall / poses if poses else math.nan,
        "cpu_hz": poses / cpu if poses and cpu > 0 else math.nan,
        "success": float(ok.mean()) if len(ok) else math.nan,
        "unresolved": float(1.0 - ok.mean()) if len(ok) else math.nan,
        "error_m_median": float(np.median(c["error_m"][ok])) if ok.any() else math.nan,
        "yaw_error_deg_median": float(np.median(c["yaw_error_deg"][ok])) if ok.any() else math.nan,
        "points_median": float(np.median(c["points"])) if len(c["points"]) else math.nan,
        "start_up_included": True,
    }


def success(rows: list[dict], band: tuple[int, int]) -> dict:
    """Finding f for a command matcher: matcher_findings.success_curve's node, with the share of accurate steps
    (ACCURATE_M, ACCURATE_DEG) per bin, in the band and below it beside."""
    mid = rows[0]["matcher"] if rows else ""
    node = matcher_findings.success_curve(rows, [mid], band)
    c = matcher_findings.columns(rows, mid)
    accurate = (c["ok"] == 1) & (c["error_m"] <= ACCURATE_M) & (c["yaw_error_deg"] <= ACCURATE_DEG)
    in_band, below = (c["points"] >= band[0]) & (c["points"] <= band[1]), c["points"] < band[0]
    mine = node["matchers"][mid]
    edges = np.asarray(node["bin_edges"])
    idx = np.digitize(c["points"], edges) - 1
    mine["accurate"] = [float(accurate[idx == b].mean()) if (idx == b).any() else None for b in range(len(edges) - 1)]
    mine["band_accurate"] = float(accurate[in_band].mean()) if in_band.any() else math.nan
    mine["below_accurate"] = float(accurate[below].mean()) if below.any() else math.nan
    mine["accurate_m"], mine["accurate_deg"] = ACCURATE_M, ACCURATE_DEG
    return node


def drift(s: Scored, mid: str, trajectory, compass_t: np.ndarray, compass_error: np.ndarray) -> dict:
    """Finding h for a command matcher: matcher_findings.yaw_drift of its poses laid onto the truth at its first pose."""
    truth = trajectory.poses(np.asarray(s.scan_t, dtype=float))
    have = np.isfinite(s.placed).all(axis=(1, 2))
    pose = np.full_like(s.placed, np.nan)
    if have.any():
        i = int(np.argmax(have))
        pose[have] = truth[i] @ np.linalg.inv(s.placed[i]) @ s.placed[have]
    n = len(s.scan_t)
    track = MatcherTrack(have, np.zeros(n, bool), np.zeros(n, bool), s.points, np.full(n, np.nan), pose)
    return matcher_findings.yaw_drift(mid, [ChainPiece(np.asarray(s.scan_t, dtype=float), truth, track)], compass_t, compass_error)


def estimator_sample(s: Scored, g: GnssSample, trajectory) -> GnssSample:
    """The receiver's epochs with the estimator's horizontal error in place of the receiver's (the pose of the scan at or
    before each epoch, within a revolution; quality 1 where it has one, 0 where not): what findings b and d read."""
    truth = trajectory.poses(np.asarray(s.scan_t, dtype=float))
    t = g.fixes.t
    idx = np.searchsorted(s.scan_t, t, side="right") - 1
    near = (idx >= 0) & (t - s.scan_t[np.clip(idx, 0, None)] <= (s.scan_t[1] - s.scan_t[0] if len(s.scan_t) > 1 else 0.1))
    error = np.full((len(t), 3), np.nan)
    j = np.clip(idx, 0, len(s.scan_t) - 1)
    diff = s.placed[j, :3, 3] - truth[j, :3, 3]
    ok = near & np.isfinite(diff).all(axis=1)
    error[ok] = diff[ok]
    fixes = dataclasses.replace(g.fixes, error=np.nan_to_num(error), quality=np.where(ok, 1, 0))
    return dataclasses.replace(g, fixes=fixes)


def judged(key: str, finding: Finding, measured: dict, builtin: dict) -> dict:
    """A component's node in one finding: its verdict, headline, checks and measurements (`builtin`: the finding's
    measured node under the first setup, for e's comparison with Method 1 and Method 2)."""
    checks = RULES[key](measured, finding, builtin)
    return {"verdict": verdict(checks), "headline": HEADLINES[key](measured), "checks": [c.as_dict() for c in checks], "measured": measured}


def _checks_e(m: dict, finding: Finding, builtin: dict) -> list[Check]:
    floor = finding.figures["method2_min_hz"]
    p = builtin.get("pcl6d", {})
    nan = math.nan
    return [
        Check(
            f"keeps up with the LiDAR as Method 2 does (>= {floor:g} Hz over its whole run, start-up included)",
            f">= {floor:g} Hz",
            f"{_f(m['hz'], '.1f', ' Hz')} (CPU time: {_f(m['cpu_hz'], '.1f', ' Hz')})",
            _holds(m["hz"], lambda v: v >= floor),
        ),
        Check(
            "as precise as Method 1 (median translation error of its steps at or below pcl6d's)",
            "Method 1's precision",
            f"{_f(m['error_m_median'], '.3f', ' m')} vs {_f(p.get('error_m_median', nan), '.3f', ' m')}",
            _holds(m["error_m_median"] - p.get("error_m_median", nan), lambda v: v <= 0.0),
        ),
        Check(
            "leaves no more matches unresolved than Method 1",
            "Method 1's",
            f"{_f(100 * m['unresolved'], '.1f', ' %')} vs {_f(100 * p.get('unresolved', nan), '.1f', ' %')}",
            _holds(m["unresolved"] - p.get("unresolved", nan), lambda v: v <= 0.0),
        ),
    ]


def _headline_e(m: dict) -> str:
    return (
        f"{_f(m['hz'], '.0f', ' Hz')} over its run (CPU time: {_f(m['cpu_hz'], '.0f', ' Hz')}), {_f(100 * m['unresolved'], '.0f', ' %')} "
        f"unresolved, {_f(m['error_m_median'], '.3f', ' m')} ({m['registrations']} steps)"
    )


def _headline_f(m: dict) -> str:
    ((mid, v),) = m["matchers"].items()
    return (
        headline("f", m)
        + f"; within {v['accurate_m']:g} m and {v['accurate_deg']:g} deg of the true step: {_f(100 * v['band_accurate'], '.0f', ' %')} in band, "
        f"{_f(100 * v['below_accurate'], '.0f', ' %')} below"
    )


RULES = {
    "b": lambda m, f, _: checks_b(m, f),
    "d": lambda m, f, _: checks_d(m, f),
    "e": _checks_e,
    "f": lambda m, f, _: checks_f(m, f),
    "h": lambda m, f, _: checks_h(m, f),
}
"""A component's checks in each finding it applies to: the built-ins' rules, but for e (a third method beside the two)."""
HEADLINES = {
    "b": lambda m: headline("b", m),
    "d": lambda m: headline("d", m),
    "e": _headline_e,
    "f": _headline_f,
    "h": lambda m: headline("h", m),
}


def measure_matcher(s: Scored, mid: str, keys: tuple[str, ...], trajectory, band: tuple[int, int], compass) -> dict:
    """A command matcher's measured node per finding in `keys`."""
    rows = matcher_rows(s, mid, trajectory)
    out: dict = {}
    if "e" in keys:
        out["e"] = rate(rows, s)
    if "f" in keys:
        out["f"] = success(rows, band)
    if "h" in keys:
        out["h"] = drift(s, mid, trajectory, *compass)
    return out


def measure_estimator(s: Scored, g: GnssSample, keys: tuple[str, ...], trajectory, structures: list[dict], n_fixes: int) -> dict:
    """A command estimator's measured node per finding in `keys`, under the setup whose receiver `g` is: b with the
    receiver's blackouts and its open-water p95 as the bar, d on the receiver's open water."""
    windows = win.find(g.fixes, [], g.period_s)
    mask = gnss_findings.open_water(g, windows, gnss_findings.shadowed(structures), reflections=False)
    bar = float(np.percentile(g.fixes.horizontal_error[mask], 95)) if mask.any() else math.nan
    mine = estimator_sample(s, g, trajectory)
    out: dict = {}
    if "b" in keys:
        out["b"] = gnss_findings.after_outages(mine, windows, bar, n_fixes)
    if "d" in keys:
        have = mask & (mine.fixes.quality == 1)
        out["d"] = {"fixes": int(have.sum()), "error": metrics.stats(mine.fixes.horizontal_error[have]), "epochs": int(mask.sum())}
    return out
