"""Run metrics (scenarios.score.metrics), degradation windows (scenarios.score.windows), the recorder's odometry
chaining (scenarios.score.record) and TUM files (scenarios.pipeline.files) against independent computations on
analytic trajectories: closed-form values or plain loops, never the function under test again."""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from matcher.result import MatchResult
from riverbench import unixtime
from scenarios.pipeline import files
from scenarios.score import metrics, units
from scenarios.score import windows as win
from scenarios.score.record import Column, FixTable, MatcherTrack, Recorder, RunRecord

FAST = settings(max_examples=40, deadline=None)
STAT_KEYS = ("rmse", "mean", "median", "p95", "max")


# ---------------------------------------------------------------- helpers (independent of the code under test)


def pose(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """4x4 world<-body pose from planar position and yaw (radians)."""
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.eye(4)
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = c, -s, s, c
    out[0, 3], out[1, 3], out[2, 3] = x, y, z
    return out


def track(xs, ys, yaws) -> np.ndarray:
    return np.array([pose(x, y, a) for x, y, a in zip(xs, ys, yaws)])


def line(n: int, step: float = 0.5, y: float = 0.0) -> np.ndarray:
    """n poses along +x, `step` metres apart, heading along x."""
    return track([step * i for i in range(n)], [y] * n, [0.0] * n)


def arc(n: int, radius: float = 50.0, dtheta: float = 0.01) -> np.ndarray:
    """n poses on a circle about the origin, heading along the tangent (counter-clockwise)."""
    return track(
        [radius * math.cos(dtheta * i) for i in range(n)],
        [radius * math.sin(dtheta * i) for i in range(n)],
        [dtheta * i + math.pi / 2 for i in range(n)],
    )


def rigid(angle: float, tx: float, ty: float) -> np.ndarray:
    return pose(tx, ty, angle)


def hand_stats(values) -> dict:
    """rmse, mean, median, p95 (linear interpolation between closest ranks), max over finite values, by hand."""
    v = sorted(float(x) for x in values if math.isfinite(x))
    n = len(v)
    median = v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2
    rank = 0.95 * (n - 1)
    lo = int(math.floor(rank))
    hi = min(lo + 1, n - 1)
    return {
        "rmse": math.sqrt(sum(x * x for x in v) / n),
        "mean": sum(v) / n,
        "median": median,
        "p95": v[lo] + (rank - lo) * (v[hi] - v[lo]),
        "max": v[-1],
    }


def assert_stats(got: dict, expected: dict, abs_tol: float = 1e-9) -> None:
    for k in STAT_KEYS:
        assert got[k] == pytest.approx(expected[k], abs=abs_tol), k


def fix_table(t, quality=None, error=None, open_sky=None, nlos=None, trusted=None, statistic=None, hdop=None) -> FixTable:
    n = len(t)
    quality = np.ones(n, dtype=int) if quality is None else np.asarray(quality, dtype=int)
    error = np.zeros((n, 3)) if error is None else np.asarray(error, dtype=float)
    open_sky = np.zeros((n, 3)) if open_sky is None else np.asarray(open_sky, dtype=float)
    return FixTable(
        t=np.asarray(t, dtype=float),
        quality=quality,
        enu=np.zeros((n, 3)),
        lat=np.zeros(n),
        lon=np.zeros(n),
        alt=np.zeros(n),
        num_sats=np.full(n, 8),
        hdop=np.ones(n) if hdop is None else np.asarray(hdop, dtype=float),
        error=error,
        open_sky_error=open_sky,
        nlos_used=np.zeros(n, dtype=bool) if nlos is None else np.asarray(nlos, dtype=bool),
        trusted={k: np.asarray(v, dtype=bool) for k, v in (trusted or {}).items()},
        statistic={k: np.asarray(v, dtype=float) for k, v in (statistic or {}).items()},
    )


def run_record(truth, estimates=None, matches=None, fixes=None, t=None) -> RunRecord:
    n = len(truth)
    estimates = estimates or {}
    if fixes is None:
        fixes = fix_table(np.zeros(0), trusted={e: [] for e in estimates}, statistic={e: [] for e in estimates})
    return RunRecord(
        scan_t=np.arange(n) / 10 if t is None else np.asarray(t, dtype=float), truth=truth, estimates=estimates, matches=matches or {}, fixes=fixes
    )


def estimator(truth, est, windows=()) -> dict:
    return metrics.estimator_metrics(run_record(truth, {"e": est}), "e", list(windows))


# ---------------------------------------------------------------- APE


def test_ape_constant_offset_3_4_is_5_everywhere():
    truth = line(50)
    est = truth.copy()
    est[:, 0, 3] += 3.0
    est[:, 1, 3] += 4.0
    out = estimator(truth, est)
    assert_stats(out["ape"], dict.fromkeys(STAT_KEYS, 5.0))
    assert out["available"] == 1.0


def test_ape_linearly_growing_offset_matches_hand_stats():
    n = 37
    truth = line(n)
    est = truth.copy()
    offsets = [0.25 * i for i in range(n)]  # growing lateral offset: error i is 0.25 i
    for i in range(n):
        est[i, 1, 3] += offsets[i]
    assert_stats(estimator(truth, est)["ape"], hand_stats(offsets))
    # numpy written independently of metrics.stats (default linear percentile)
    v = np.array(offsets)
    assert estimator(truth, est)["ape"]["p95"] == pytest.approx(float(np.percentile(v, 95)))


def test_ape_ignores_uninitialised_rows_and_available_is_their_complement():
    n, missing = 40, 12
    truth = line(n)
    est = truth.copy()
    errors = []
    for i in range(n):
        est[i, 0, 3] += 0.1 * i
        errors.append(0.1 * i)
    est[:missing] = np.nan
    out = estimator(truth, est)
    assert out["available"] == pytest.approx((n - missing) / n)
    assert_stats(out["ape"], hand_stats(errors[missing:]))


def test_ape_all_nan_is_nan():
    truth = line(10)
    out = estimator(truth, np.full_like(truth, np.nan))
    assert out["available"] == 0.0
    assert all(math.isnan(out["ape"][k]) for k in STAT_KEYS)
    assert out["rpe_10m"]["pairs"] == 0 and math.isnan(out["rpe_10m"]["percent"])


@FAST
@given(dx=st.floats(-50, 50), dy=st.floats(-50, 50), heading=st.floats(-math.pi, math.pi))
def test_ape_of_random_constant_offset_is_its_norm(dx, dy, heading):
    n = 30
    truth = track([0.7 * i * math.cos(heading) for i in range(n)], [0.7 * i * math.sin(heading) for i in range(n)], [heading] * n)
    est = truth.copy()
    est[:, 0, 3] += dx
    est[:, 1, 3] += dy
    assert_stats(estimator(truth, est)["ape"], dict.fromkeys(STAT_KEYS, math.hypot(dx, dy)), abs_tol=1e-7)


# ---------------------------------------------------------------- RPE


def expected_pairs(s: list[float], d: float, finite: list[bool] | None = None) -> int:
    """Scans i that have a scan j at least d metres further along (both finite), by a plain double loop."""
    count = 0
    for i in range(len(s)):
        for j in range(i, len(s)):
            if s[j] >= s[i] + d:
                if finite is None or (finite[i] and finite[j]):
                    count += 1
                break
    return count


def test_rpe_of_constant_offset_is_zero_and_pairs_count_scans_with_one_d_further():
    n, step = 300, 0.5  # 149.5 m at 0.5 m per scan (exact in binary)
    truth = line(n, step)
    est = truth.copy()
    est[:, 0, 3] += 3.0
    est[:, 1, 3] -= 7.0
    out = estimator(truth, est)
    s = [step * i for i in range(n)]
    for d in (10, 100):
        r = out[f"rpe_{d}m"]
        assert r["pairs"] == expected_pairs(s, d) == n - int(d / step)
        assert r["max"] == pytest.approx(0.0, abs=1e-9)
        assert r["percent"] == pytest.approx(0.0, abs=1e-7)


def test_rpe_of_scale_error_is_a_tenth_of_the_distance():
    n, step = 300, 0.5
    truth = line(n, step)
    est = track([1.1 * step * i for i in range(n)], [0.0] * n, [0.0] * n)  # moves 1.1x as far
    out = estimator(truth, est)
    for d in (10, 100):
        r = out[f"rpe_{d}m"]
        assert_stats(r, dict.fromkeys(STAT_KEYS, 0.1 * d), abs_tol=1e-7)
        assert r["percent"] == pytest.approx(10.0)
    assert out["rpe_10m"]["mean"] == pytest.approx(1.0)


def test_rpe_is_frame_relative_rotated_estimate_has_zero_rpe_but_ape():
    n, step, phi = 300, 0.5, math.radians(20.0)
    truth = line(n, step, y=2.0)
    about_start = pose(0.0, 2.0, 0.0) @ pose(0.0, 0.0, phi) @ np.linalg.inv(pose(0.0, 2.0, 0.0))
    est = np.array([about_start @ p for p in truth])  # same motion in its own frame, rotated about the start
    out = estimator(truth, est)
    assert out["rpe_10m"]["max"] == pytest.approx(0.0, abs=1e-9)
    assert out["rpe_100m"]["max"] == pytest.approx(0.0, abs=1e-9)
    chord = [2 * math.sin(phi / 2) * step * i for i in range(n)]  # distance between a point and its rotation about the start
    assert_stats(out["ape"], hand_stats(chord), abs_tol=1e-7)
    assert out["ape"]["max"] > 40.0
    assert_stats(out["yaw"], dict.fromkeys(STAT_KEYS, 20.0), abs_tol=1e-9)


def test_rpe_pairs_skip_uninitialised_scans():
    n, step, missing = 300, 0.5, 15
    truth = line(n, step)
    est = truth.copy()
    est[:missing] = np.nan
    out = estimator(truth, est)
    s = [step * i for i in range(n)]
    finite = [i >= missing for i in range(n)]
    assert out["rpe_10m"]["pairs"] == expected_pairs(s, 10.0, finite) == n - 20 - missing


def test_rpe_on_a_curve_with_a_turning_offset_matches_a_loop():
    """A yaw error that grows with time: RPE compares displacements in each pose's own frame, by hand."""
    n = 120
    truth = arc(n, radius=30.0, dtheta=0.02)
    est = truth.copy()
    for i in range(n):  # wrong heading (not position): the estimate's own frame is turned by 0.001 i rad
        est[i, :3, :3] = pose(0, 0, math.atan2(truth[i, 1, 0], truth[i, 0, 0]) + 0.001 * i)[:3, :3]
    step = 2 * 30.0 * math.sin(0.01)  # chord between consecutive poses
    errors = []
    for i in range(n):
        j = next((j for j in range(i, n) if (j - i) * step >= 10.0 - 1e-9), None)
        if j is None:
            continue
        dx, dy = truth[j, 0, 3] - truth[i, 0, 3], truth[j, 1, 3] - truth[i, 1, 3]
        a_true = 0.02 * i + math.pi / 2
        a_est = a_true + 0.001 * i
        rt = (math.cos(a_true) * dx + math.sin(a_true) * dy, -math.sin(a_true) * dx + math.cos(a_true) * dy)
        re = (math.cos(a_est) * dx + math.sin(a_est) * dy, -math.sin(a_est) * dx + math.cos(a_est) * dy)
        errors.append(math.hypot(re[0] - rt[0], re[1] - rt[1]))
    r = estimator(truth, est)["rpe_10m"]
    assert r["pairs"] == len(errors)
    assert_stats(r, hand_stats(errors), abs_tol=1e-9)


@FAST
@given(dx=st.floats(-100, 100), dy=st.floats(-100, 100), heading=st.floats(-math.pi, math.pi), speed=st.floats(0.2, 3.0))
def test_rpe_of_random_constant_offset_is_zero(dx, dy, heading, speed):
    n = 80
    truth = track([speed * i * math.cos(heading) for i in range(n)], [speed * i * math.sin(heading) for i in range(n)], [heading] * n)
    est = truth.copy()
    est[:, 0, 3] += dx
    est[:, 1, 3] += dy
    r = metrics.rpe(est, truth, 10.0)
    assert r["pairs"] > 0
    assert r["max"] == pytest.approx(0.0, abs=1e-8)


# ---------------------------------------------------------------- yaw


def test_yaw_error_wraps_around():
    truth = track([0.0] * 5, [0.0] * 5, [math.radians(-179.0)] * 5)
    est = track([0.0] * 5, [0.0] * 5, [math.radians(179.0)] * 5)
    assert_stats(estimator(truth, est)["yaw"], dict.fromkeys(STAT_KEYS, 2.0), abs_tol=1e-9)


@FAST
@given(a=st.floats(-720, 720), b=st.floats(-720, 720))
def test_yaw_error_is_the_shortest_angle_for_random_angles(a, b):
    expected = min(abs(a - b + 360.0 * k) for k in range(-5, 6))
    got = metrics.yaw_error_deg(track([0.0], [0.0], [math.radians(a)]), track([0.0], [0.0], [math.radians(b)]))[0]
    assert 0.0 <= got <= 180.0 + 1e-9
    assert got == pytest.approx(expected, abs=1e-6)


# ---------------------------------------------------------------- matchers: alignment and counters


def matcher_track(pose_, ok=None, gated=None, degenerate=None, points=None, seconds=None) -> MatcherTrack:
    n = len(pose_)
    return MatcherTrack(
        ok=np.ones(n, bool) if ok is None else np.asarray(ok, bool),
        gated=np.zeros(n, bool) if gated is None else np.asarray(gated, bool),
        degenerate=np.zeros(n, bool) if degenerate is None else np.asarray(degenerate, bool),
        points=np.full(n, 1000) if points is None else np.asarray(points, int),
        seconds=np.full(n, 0.05) if seconds is None else np.asarray(seconds, float),
        pose=pose_,
    )


def test_align_se2_removes_a_rigid_motion_of_the_whole_track():
    n = 100
    truth = arc(n)
    motion = rigid(math.radians(30.0), 10.0, -5.0)
    odom = np.array([motion @ p for p in truth])
    out = metrics.matcher_metrics(run_record(truth, matches={"m": matcher_track(odom)}), "m")
    moved = [math.hypot(odom[i, 0, 3] - truth[i, 0, 3], odom[i, 1, 3] - truth[i, 1, 3]) for i in range(n)]
    assert_stats(out["ape"], hand_stats(moved), abs_tol=1e-9)
    assert out["ape"]["mean"] > 10.0
    assert out["ape_aligned"]["max"] == pytest.approx(0.0, abs=1e-8)
    assert out["rpe_10m"]["max"] == pytest.approx(0.0, abs=1e-8)  # the odometry's own motion is exact
    assert_stats(out["yaw"], dict.fromkeys(STAT_KEYS, 30.0), abs_tol=1e-9)


def test_align_se2_ignores_nan_rows_and_keeps_them_nan():
    truth = arc(60)
    odom = np.array([rigid(-1.0, 3.0, 4.0) @ p for p in truth])
    odom[:5] = np.nan
    aligned = metrics.align_se2(odom, truth)
    assert np.isnan(aligned[:5]).all()
    assert np.allclose(aligned[5:, :2, 3], truth[5:, :2, 3], atol=1e-8)


def test_align_se2_best_fit_beats_any_nearby_motion():
    """On a noisy track the fit is a least-squares minimum: perturbing it never lowers the squared error."""
    rng = np.random.default_rng(3)
    truth = arc(80)
    odom = np.array([rigid(0.4, -7.0, 2.0) @ p for p in truth])
    odom[:, :2, 3] += rng.normal(0.0, 0.5, (80, 2))
    aligned = metrics.align_se2(odom, truth)
    sse = lambda est: sum((est[i, 0, 3] - truth[i, 0, 3]) ** 2 + (est[i, 1, 3] - truth[i, 1, 3]) ** 2 for i in range(80))
    best = sse(aligned)
    centre = aligned[:, :2, 3].mean(axis=0)
    about = pose(centre[0], centre[1], 0.0)
    for da, tx, ty in [(1e-3, 0, 0), (-1e-3, 0, 0), (0, 0.01, 0), (0, -0.01, 0), (0, 0, 0.01), (0, 0, -0.01)]:
        nudged = np.array([pose(tx, ty, 0.0) @ about @ pose(0, 0, da) @ np.linalg.inv(about) @ p for p in aligned])
        assert sse(nudged) > best


@FAST
@given(angle=st.floats(-math.pi, math.pi), tx=st.floats(-500, 500), ty=st.floats(-500, 500))
def test_align_se2_recovers_random_rigid_motions(angle, tx, ty):
    truth = arc(40, radius=20.0, dtheta=0.05)
    odom = np.array([rigid(angle, tx, ty) @ p for p in truth])
    aligned = metrics.align_se2(odom, truth)
    assert np.abs(aligned[:, :2, 3] - truth[:, :2, 3]).max() < 1e-6


def test_matcher_counters_success_gated_degenerate_hz_points():
    n = 10
    truth = line(n)
    ok = [False, True, True, False, False, True, True, True, True, True]  # scan 0: nothing to match against
    gated = [False, False, False, True, False, False, False, False, False, False]  # scan 3 gated (so not ok)
    degenerate = [False, True, False, False, False, False, True, True, False, False]
    seconds = [0.5, 0.02, 0.04, 0.001, 0.03, 0.05, 0.02, 0.06, 0.04, 0.03]
    points = [100, 200, 300, 400, 500, 600, 700, 800, 900, 1000]
    out = metrics.matcher_metrics(run_record(truth, matches={"m": matcher_track(truth, ok, gated, degenerate, points, seconds)}), "m")
    assert out["success"] == pytest.approx(sum(ok[1:]) / 9)  # 7 of the 9 attempts
    assert out["gated"] == pytest.approx(1 / 10)
    n_ok = sum(ok)
    assert out["degenerate"] == pytest.approx(sum(d for d, o in zip(degenerate, ok) if o) / n_ok)  # 3 of 7
    attempts = sorted(s for i, s in enumerate(seconds) if i > 0 and not gated[i])  # 8 registered: the gated scan costs nothing
    assert out["hz"] == pytest.approx(1.0 / np.median(attempts))
    assert out["ms"]["median"] == pytest.approx(1e3 * np.median(attempts))
    assert out["ms"]["p95"] == pytest.approx(1e3 * hand_stats(attempts)["p95"])
    assert out["points"]["median"] == pytest.approx(550.0)
    assert out["points"]["p10"] == pytest.approx(100 + 0.9 * 100)  # rank 0.9 between 100 and 200
    assert out["points"]["p90"] == pytest.approx(900 + 0.1 * 100)  # rank 8.1 between 900 and 1000
    assert out["failed"] is False


def test_matcher_failure_is_reported_with_its_stamp():
    truth = line(5)
    rec = run_record(truth, matches={"m": matcher_track(truth)})
    rec.failures = [
        {"component": "matcher", "id": "other", "stamp": 0.1, "reason": "x"},
        {"component": "matcher", "id": "m", "stamp": 0.3, "reason": "worker died"},
    ]
    out = metrics.matcher_metrics(rec, "m")
    assert out["failed"] is True and out["failed_at"] == 0.3


# ---------------------------------------------------------------- recorder: odometry chaining

MOUNT = np.array(pose(1.2, -0.3, 0.1, z=2.5))
MOUNT[:3, :3] = Rotation.from_euler("xyz", [2.0, -4.0, 5.0], degrees=True).as_matrix()  # tilted lidar


def relative(truth_i, truth_j):
    """Exact lidar motion from scan i to scan j."""
    return np.linalg.inv(truth_i @ MOUNT) @ truth_j @ MOUNT


def good(T, ref_stamp, degenerate=False):
    return MatchResult(T=T, ok=True, cov=None, n_points=1000, seconds=0.01, info={"ref_stamp": ref_stamp, "degenerate": degenerate})


def chain(truth, results, t=None):
    t = np.arange(len(truth)) / 10 if t is None else t
    rec = Recorder(["m"], [], MOUNT)
    for i, r in enumerate(results):
        rec.scan(float(t[i]), truth[i], {"m": r}, {})
    return rec.finish([]).matches["m"]


def test_recorder_chains_exact_relative_motion_into_the_truth():
    truth = arc(30, radius=25.0, dtheta=0.03)
    t = np.arange(30) / 10
    results = [MatchResult.failure("first scan", n_points=1000)]
    results += [good(relative(truth[i - 1], truth[i]), t[i - 1], degenerate=(i == 4)) for i in range(1, 30)]
    m = chain(truth, results, t)
    assert np.allclose(m.pose, truth, atol=1e-9)
    assert not m.ok[0] and m.ok[1:].all()
    assert m.degenerate.tolist() == [i == 4 for i in range(30)]


def test_recorder_failed_match_loses_that_step_and_holds_the_pose():
    """A straight run at constant heading: after a failed match at scan k (the matcher restarts from
    scan k), every later pose lags the truth by exactly one step."""
    n, k, step, heading = 20, 7, 0.8, 0.3
    truth = track([step * i * math.cos(heading) for i in range(n)], [step * i * math.sin(heading) for i in range(n)], [heading] * n)
    t = np.arange(n) / 10
    results = [MatchResult.failure("first scan")]
    for i in range(1, n):
        if i == k:
            results.append(MatchResult.failure("no convergence", n_points=800, ref_stamp=t[i - 1]))
        else:
            results.append(good(relative(truth[i - 1], truth[i]), t[i - 1]))
    m = chain(truth, results, t)
    for i in range(n):
        lag = step if i >= k else 0.0
        assert m.pose[i, 0, 3] == pytest.approx(truth[i, 0, 3] - lag * math.cos(heading), abs=1e-9)
        assert m.pose[i, 1, 3] == pytest.approx(truth[i, 1, 3] - lag * math.sin(heading), abs=1e-9)
    assert np.allclose(m.pose[k], m.pose[k - 1])
    assert not m.ok[k] and not m.gated[k]


def test_recorder_gated_scan_holds_the_pose_and_is_not_a_reference():
    truth = arc(20, radius=25.0, dtheta=0.04)
    t = np.arange(20) / 10
    gated = {5, 6, 11}
    results = [MatchResult.failure("first scan")]
    last_ref = 0
    for i in range(1, 20):
        if i in gated:
            results.append(MatchResult.failure("too few points", n_points=12, gated=True))
            continue
        results.append(good(relative(truth[last_ref], truth[i]), t[last_ref]))
        last_ref = i
    m = chain(truth, results, t)
    for i in range(20):
        if i in gated:
            held = max(j for j in range(i) if j not in gated)
            assert np.allclose(m.pose[i], truth[held], atol=1e-9), i
        else:
            assert np.allclose(m.pose[i], truth[i], atol=1e-9), i
    assert m.gated.tolist() == [i in gated for i in range(20)]
    assert m.points[5] == 12


def test_recorder_gated_scans_before_the_first_reference_do_not_become_it():
    """The matcher's first reference is its first scan that passes the gate: the odometry starts from
    the true pose there (before it there is no odometry: NaN), so no motion is lost."""
    truth = line(12, step=1.0)
    t = np.arange(12) / 10
    results = [MatchResult.failure("too few points", n_points=3, gated=True)] * 3
    results += [MatchResult.failure("first scan", n_points=900)]
    results += [good(relative(truth[i - 1], truth[i]), t[i - 1]) for i in range(4, 12)]
    m = chain(truth, results, t)
    assert np.isnan(m.pose[:3]).all()
    assert np.allclose(m.pose[3:], truth[3:], atol=1e-9)


# ---------------------------------------------------------------- windows


def test_find_blackout_reacquisition_and_injected_at_5hz():
    t = [i / 5 for i in range(7)]
    quality = [1, 1, 0, 0, 6, 1, 1]
    error = np.zeros((7, 3))
    open_sky = np.zeros((7, 3))
    open_sky[:, 0] = 0.5
    error[5] = (3.5, 0.0, 0.0)  # added 3 m: still re-acquiring
    error[6] = (0.9, 0.2, 10.0)  # added hypot(0.4, 0.2) < 1 m horizontally (the vertical does not count)
    fixes = fix_table(t, quality, error, open_sky)
    windows = win.find(fixes, [(0.5, 0.9), (100.0, 110.0)], 0.2)
    assert windows == [win.Window("blackout", 0.4, 1.0), win.Window("injected", 0.5, 0.9), win.Window("reacquisition", 1.0, 1.2)]
    assert windows[0].duration == pytest.approx(0.6)


def test_reacquisition_ends_on_added_error_not_true_error_and_may_be_empty():
    t = [i / 5 for i in range(6)]
    error = np.zeros((6, 3))
    open_sky = np.zeros((6, 3))
    error[3:] = (20.0, 0.0, 0.0)
    open_sky[3:] = (19.5, 0.0, 0.0)  # large true error, but the environment adds only 0.5 m
    windows = win.find(fix_table(t, [1, 0, 0, 1, 1, 1], error, open_sky), [], 0.2)
    assert windows == [win.Window("blackout", 0.2, 0.6)]  # re-acquired at once: no reacquisition window


def test_reacquisition_never_done_runs_to_the_last_fix_plus_a_period():
    t = [i / 5 for i in range(6)]
    error = np.zeros((6, 3))
    error[3:] = (4.0, 0.0, 0.0)
    windows = win.find(fix_table(t, [1, 0, 0, 1, 1, 1], error), [], 0.2)
    reacq = [w for w in windows if w.kind == "reacquisition"]
    assert len(reacq) == 1
    assert reacq[0].start == pytest.approx(0.6) and reacq[0].end == pytest.approx(1.0 + 0.2)


def test_blackout_at_the_end_runs_one_period_past_the_last_fix():
    t = [i / 5 for i in range(5)]
    windows = win.find(fix_table(t, [1, 1, 1, 0, 0]), [], 0.2)
    assert windows == [win.Window("blackout", 0.6, 0.8 + 0.2)]


def test_nlos_runs_closer_than_a_second_merge():
    t = [i / 5 for i in range(30)]  # 0 .. 5.8 s
    nlos = [False] * 30
    for i in (1, 2, 6, 15, 29):
        nlos[i] = True
    windows = win.find(fix_table(t, nlos=nlos), [], 0.2)
    # [0.2, 0.6) and [1.2, 1.4) are 0.6 s apart: one window; 3.0 is 1.6 s after 1.4; 5.8 is the last fix
    assert windows == [win.Window("nlos", 0.2, 1.4), win.Window("nlos", 3.0, 3.2), win.Window("nlos", 5.8, 5.8 + 0.2)]


def passage_error(t: float) -> float:
    """1 m before 3 s, rising 4 m/s inside [3, 5), then 6 m until 6.5 s, 3 m until 7.2 s, 1.5 m after."""
    if t < 3.0:
        return 1.0
    if t < 5.0:
        return 1.0 + 4.0 * (t - 3.0)
    if t < 6.5:
        return 6.0
    if t < 7.2:
        return 3.0
    return 1.5


def test_passage_entry_exit_max_added_and_recovery():
    t = np.array([i / 10 for i in range(101)])
    error = np.array([passage_error(x) for x in t])
    p = win.passage(win.Window("blackout", 3.0, 5.0), t, error)
    assert p.entry_error == 1.0  # scan at 3.0 s (fed before the window's first fix)
    assert p.max_error == pytest.approx(1.0 + 4.0 * 1.9)  # scan at 4.9 s
    assert p.exit_error == 6.0  # scan at 5.1 s (the first after the end)
    assert p.added == 5.0
    assert p.recover_s == pytest.approx(2.2)  # 7.2 s: first error within 1 m of the entry's


def test_passage_never_recovering_is_nan_and_edges_of_the_run():
    t = np.array([i / 10 for i in range(50)])
    error = np.where(t <= 2.0, 1.0, 5.0)
    p = win.passage(win.Window("nlos", 2.0, 3.0), t, error)
    assert (p.entry_error, p.exit_error, p.added) == (1.0, 5.0, 4.0)
    assert math.isnan(p.recover_s)
    first = win.passage(win.Window("blackout", -1.0, 0.25), t, error)  # no scan before: entry is the first inside
    assert first.entry_error == 1.0 and first.recover_s == pytest.approx(0.05)
    last = win.passage(win.Window("blackout", 4.5, 9.0), t, error)  # no scan after: exit is the last inside
    assert last.exit_error == 5.0 and last.entry_error == 5.0 and math.isnan(last.recover_s)


def test_settling_counts_a_return_within_2_m_only_once_it_lasts():
    """Analytic: 1 m off at an NLOS window's end (5 s), 3 m off from 7.1 to 8.9 s, 1 m after: the return that lasts
    SETTLED_FOR_S (10 s) starts at 9.0 s, so settle_s is 4.0 s, not the first touch's 0.1 s; with the next window
    starting at 6.0 s the return need last only until then (0.1 s); never back to stay: NaN."""
    t = np.arange(300) / 10.0
    error = np.where((t > 7.0) & (t < 9.0), 3.0, 1.0)
    nlos = win.Window("nlos", 4.0, 5.0)
    assert win.passage(nlos, t, error).settle_s == pytest.approx(4.0)
    assert win.passage(nlos, t, error, until=6.0).settle_s == pytest.approx(0.1)
    assert math.isnan(win.passage(nlos, t, np.where(t > 7.0, 3.0, 1.0)).settle_s)
    windows = [nlos, win.Window("blackout", 6.0, 6.5)]
    assert win.next_start(nlos, windows) == 6.0 and win.next_start(windows[1], windows) == math.inf
    assert metrics.window_metrics(windows, t, error)["nlos"]["settle_s"] == pytest.approx(0.1)


def test_a_window_holds_the_scans_its_fixes_shaped_so_a_sub_nanosecond_shift_of_its_fixes_moves_nothing():
    # issue 41: at equal stamps the scan is fed before the fix, so the scan at a window's first fix has not seen it and
    # the one at the fix that ends it is still inside; with [start, end) a fix 1e-10 s later moved a scan across
    scans = np.arange(40) / 10.0
    error = np.where((scans > 1.0) & (scans <= 2.0), 20.0, 1.0)  # what the estimate had after the blackout's first fix
    quality = [1] * 5 + [0] * 5 + [1] * 10  # 5 Hz: blackout from the fix at 1.0 s to the one at 2.0 s
    passages = []
    for shift in (0.0, 1e-10, 3e-10):
        fixes = fix_table([i / 5 + shift for i in range(20)], quality)
        (blackout,) = [w for w in win.find(fixes, [], 0.2) if w.kind == "blackout"]
        assert list(scans[blackout.scans(scans)]) == [x / 10 for x in range(11, 21)]
        passages.append(win.passage(blackout, scans, error))
    errors = {(p.entry_error, p.max_error, p.exit_error, p.added) for p in passages}
    assert errors == {(1.0, 20.0, 1.0, 0.0)}  # the same scans, bit for bit
    assert [p.recover_s for p in passages] == pytest.approx([0.1] * 3)  # from the window's end: moves by the shift only


def test_window_metrics_per_kind_worst_over_windows():
    t = np.array([i / 10 for i in range(101)])
    error = np.array([passage_error(x) for x in t])
    windows = [win.Window("blackout", 3.0, 5.0), win.Window("blackout", 8.0, 8.5), win.Window("injected", 9.0, 9.5)]
    error[t > 8.0] = 30.0  # never recovers from the second blackout
    rec = run_record(np.array([pose(0, 0, 0)] * len(t)), {"e": np.array([pose(0, 0, 0)] * len(t))}, t=t)
    out = metrics.window_metrics(windows, rec.scan_t, error)
    b = out["blackout"]
    assert b["count"] == 2 and b["seconds"] == pytest.approx(2.5)
    assert b["max_error"] == 30.0 and b["exit_error"] == 30.0
    assert b["added"] == pytest.approx(30.0 - 1.5)  # entry of the second: 1.5 m at 8.0 s
    assert b["recover_s"] == pytest.approx(2.2)  # the worst finite recovery
    assert b["recovered"] == 0.5
    assert out["nlos"]["count"] == 0 and math.isnan(out["nlos"]["recovered"]) and math.isnan(out["nlos"]["max_error"])
    assert out["injected"]["count"] == 1
    assert "yaw" not in b  # no heading known (a replay's reference without one)


def test_window_heading_error_is_taken_over_the_scans_inside_that_kinds_windows():
    t = np.arange(100) / 10.0
    yaw_error = np.where((t > 2.0) & (t <= 4.0), 10.0 * t, 0.5)  # 21-40 deg inside the blackout, 0.5 deg elsewhere
    windows = [win.Window("blackout", 2.0, 4.0), win.Window("nlos", 6.0, 6.25)]
    out = metrics.window_metrics(windows, t, np.zeros(len(t)), yaw_error)
    inside = 10.0 * t[(t > 2.0) & (t <= 4.0)]
    assert out["blackout"]["yaw"] == {"p95": pytest.approx(np.percentile(inside, 95)), "max": pytest.approx(40.0)}
    assert out["nlos"]["yaw"] == {"p95": 0.5, "max": 0.5}
    assert all(math.isnan(v) for v in out["reacquisition"]["yaw"].values())  # no window of that kind: NaN
    assert units.quantity_of("estimators.ekf.windows.blackout.yaw.p95").unit == "deg"
    assert metrics.family_of("estimators.ekf.windows.nlos.yaw.max").name == "heading error"


# ---------------------------------------------------------------- monitors and GPS


def monitor_case():
    """12 fixes, 2 unmeasured; true and open-sky errors chosen so the two fault definitions differ."""
    quality = [1, 1, 1, 1, 0, 1, 1, 1, 6, 1, 1, 1]
    true_h = [1.0, 7.0, 6.0, 2.0, 0.0, 9.0, 3.0, 12.0, 0.0, 0.5, 5.5, 4.0]
    sky_h = [0.5, 0.5, 4.0, 0.5, 0.0, 1.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.0]  # along x too: added = true - sky
    trusted = [True, False, True, False, False, False, True, True, False, True, False, True]
    stat = [0.1, 5.0, 0.3, 0.9, np.nan, 4.0, 0.2, 3.0, np.nan, 0.05, 2.0, 0.4]
    error = np.zeros((12, 3))
    error[:, 0] = true_h
    sky = np.zeros((12, 3))
    sky[:, 0] = sky_h
    fixes = fix_table([i / 5 for i in range(12)], quality, error, sky, trusted={"e": trusted}, statistic={"e": stat})
    return fixes, quality, true_h, sky_h, trusted, stat


def hand_confusion(faulty: list[bool], flagged: list[bool]) -> dict:
    tp = fp = fn = tn = 0
    for f, g in zip(faulty, flagged):
        if f and g:
            tp += 1
        elif g:
            fp += 1
        elif f:
            fn += 1
        else:
            tn += 1
    return {"faulty": tp + fn, "precision": tp / (tp + fp), "recall": tp / (tp + fn), "false_alarm_rate": fp / (fp + tn)}


def brute_recall_at(stat: list[float], faulty: list[bool], max_fa: float) -> float:
    n_pos = max(sum(faulty), 1)
    n_neg = max(len(faulty) - sum(faulty), 1)
    best = 0.0
    for thr in [s for s in stat if not math.isnan(s)]:
        flagged = [not math.isnan(s) and s >= thr for s in stat]
        fa = sum(g and not f for g, f in zip(flagged, faulty)) / n_neg
        rec = sum(g and f for g, f in zip(flagged, faulty)) / n_pos
        if fa <= max_fa + 1e-12:
            best = max(best, rec)
    return best


def test_monitor_metrics_precision_recall_false_alarms_by_hand():
    fixes, quality, true_h, sky_h, trusted, stat = monitor_case()
    out = metrics.monitor_metrics(fixes, "e")
    rows = [i for i in range(12) if quality[i] == 1]
    flagged = [not trusted[i] for i in rows]
    for name, faulty in (("error_5m", [true_h[i] > 5.0 for i in rows]), ("added_5m", [true_h[i] - sky_h[i] > 5.0 for i in rows])):
        expected = hand_confusion(faulty, flagged)
        for k, v in expected.items():
            assert out[name][k] == pytest.approx(v), (name, k)
        assert out[name]["recall_at_5pct_fa"] == pytest.approx(brute_recall_at([stat[i] for i in rows], faulty, 0.05))
    assert out["error_5m"]["faulty"] == 5 and out["added_5m"]["faulty"] == 4  # 6.0 m at fix 2 adds only 2 m
    # written out: error_5m faulty rows 1,2,5,7,10; flagged rows 1,3,5,10 -> tp 3 (1,5,10), fp 1 (3)
    assert out["error_5m"]["precision"] == pytest.approx(3 / 4)
    assert out["error_5m"]["recall"] == pytest.approx(3 / 5)
    assert out["error_5m"]["false_alarm_rate"] == pytest.approx(1 / 5)


def test_recall_at_5pct_fa_is_one_when_the_statistic_separates():
    faulty = np.array([i % 4 == 0 for i in range(40)])
    statistic = np.where(faulty, 10.0 + np.arange(40), np.arange(40) / 100)
    assert metrics.recall_at(statistic, faulty, 0.05) == 1.0
    assert math.isnan(metrics.recall_at(statistic, np.zeros(40, bool), 0.05))


def test_recall_at_with_a_negative_above_the_positives():
    faulty = np.array([True, True, True] + [False] * 20)
    stat = np.array([10.0, 9.0, 3.0, 8.0, 7.0] + [1.0] * 18)
    # >= 8 flags 1/20 negatives (allowed) and 2/3 positives; reaching 3.0 costs 2/20 = 10 % false alarms
    assert metrics.recall_at(stat, faulty, 0.05) == pytest.approx(2 / 3)


@FAST
@given(st.lists(st.tuples(st.one_of(st.integers(0, 6).map(float), st.just(math.nan)), st.booleans()), min_size=1, max_size=40))
def test_recall_at_equals_a_brute_force_threshold_sweep(rows):
    stat = [s for s, _ in rows]
    faulty = [f for _, f in rows]
    if not any(faulty):
        faulty[0] = True
    for budget in (0.0, 0.05, 0.3):
        assert metrics.recall_at(np.array(stat), np.array(faulty), budget) == pytest.approx(brute_recall_at(stat, faulty, budget))


def test_gps_metrics_over_measured_fixes():
    fixes, quality, true_h, sky_h, _, _ = monitor_case()
    fixes.nlos_used[:] = [False, True, True, False, False, False, False, True, False, False, False, False]
    fixes.hdop[:] = [1.0, 2.0, 3.0, 4.0, 99.0, 5.0, 6.0, 7.0, 99.0, 8.0, 9.0, 10.0]
    out = metrics.gps_metrics(fixes)
    measured = [i for i in range(12) if quality[i] == 1]
    assert out["fixes"] == 12
    assert out["availability"] == pytest.approx(10 / 12)
    assert out["blackout"] == pytest.approx(2 / 12)
    assert out["valid"] == pytest.approx(11 / 12)  # quality 6 is valid but not measured
    assert out["nlos_share"] == pytest.approx(3 / 10)
    assert_stats(out["error"], hand_stats([true_h[i] for i in measured]))
    assert_stats(out["open_sky_error"], hand_stats([sky_h[i] for i in measured]))
    assert_stats(out["added_error"], hand_stats([true_h[i] - sky_h[i] for i in measured]))
    assert out["hdop_median"] == pytest.approx(5.5)
    assert out["faulty_5m"] == pytest.approx(5 / 10)


def test_gps_metrics_without_fixes_are_nan():
    out = metrics.gps_metrics(fix_table(np.zeros(0)))
    assert out["fixes"] == 0
    assert all(math.isnan(out[k]) for k in ("availability", "blackout", "nlos_share", "faulty_5m"))


def test_estimator_metrics_wire_windows_monitor_and_failures():
    n = 50
    truth = line(n)
    est = truth.copy()
    est[:, 0, 3] += 2.0
    fixes, *_ = monitor_case()
    rec = run_record(truth, {"e": est}, fixes=fixes)
    rec.failures = [{"component": "estimator", "id": "e", "stamp": 4.2, "reason": "boom"}]
    out = metrics.estimator_metrics(rec, "e", [win.Window("nlos", 1.0, 2.0)])
    assert out["windows"]["nlos"]["count"] == 1 and out["windows"]["nlos"]["max_error"] == pytest.approx(2.0)
    assert out["monitor"]["error_5m"]["faulty"] == 5
    assert out["failed"] is True and out["failed_at"] == 4.2


# ---------------------------------------------------------------- files and JSON


def test_tum_round_trip(tmp_path):
    rng = np.random.default_rng(11)
    n = 25
    rotations = Rotation.random(n, random_state=4)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = rotations.as_matrix()
    poses[:, :3, 3] = rng.uniform(-1000.0, 1000.0, (n, 3))
    poses[[0, 1, 7]] = np.nan  # before initialisation / after a failure: left out
    t = 100.0 + np.arange(n) / 10
    path = tmp_path / "est.tum"
    assert files.write_tum(path, t, poses) == n - 3
    with open(path) as f:
        assert f.readline().startswith("#")
    rows = files.read_tum(path)
    kept = [i for i in range(n) if i not in (0, 1, 7)]
    assert rows.shape == (n - 3, 8)
    assert np.allclose(rows[:, 0], t[kept], atol=1e-6)
    assert np.abs(rows[:, 1:4] - poses[kept, :3, 3]).max() <= 1e-6
    assert np.allclose(np.linalg.norm(rows[:, 4:8], axis=1), 1.0, atol=1e-8)
    expected = rotations[kept].as_quat()  # x, y, z, w; q and -q are the same rotation
    sign = np.where(np.sum(rows[:, 4:8] * expected, axis=1) < 0, -1.0, 1.0)
    assert np.allclose(rows[:, 4:8], sign[:, None] * expected, atol=1e-8)
    assert np.allclose(Rotation.from_quat(rows[:, 4:8]).as_matrix(), poses[kept, :3, :3], atol=1e-8)


def test_tum_with_no_finite_pose_has_only_the_header(tmp_path):
    path = tmp_path / "empty.tum"
    assert files.write_tum(path, np.arange(3.0), np.full((3, 4, 4), np.nan)) == 0
    assert path.read_text() == files.TUM_HEADER
    assert files.read_tum(path).shape[0] == 0


def test_tum_with_a_time_zero_is_in_unix_nanoseconds_and_reads_back_on_the_scenario_clock(tmp_path):
    zero = unixtime.unix_ns(datetime(2024, 6, 15, 14, 0, 0, tzinfo=UTC))
    assert zero == 1_718_460_000 * 10**9  # date -u -d 2024-06-15T14:00:00Z +%s
    t = 1974.7311226848155 + np.arange(5) / 10
    poses = track(np.arange(5.0), np.zeros(5), np.zeros(5))
    path = tmp_path / "est.tum"
    assert files.write_tum(path, t, poses, zero) == 5
    lines = path.read_text().splitlines()
    assert lines[0] == files.TUM_HEADER.strip() and lines[1].startswith(files.TIME_ZERO + " 1718460000.000000000")
    assert lines[2].split()[0] == "1718461974.731122685"  # 2024-06-15T14:32:54.731122685Z
    np.testing.assert_allclose(files.read_tum(path)[:, 0], 1718460000.0 + t, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(files.read_tum(path, scenario_time=True)[:, 0], np.round(t * 1e9) / 1e9)


@given(st.integers(-(10**19), 10**19))
@FAST
def test_unix_seconds_text_round_trips_nanoseconds(ns):
    text = unixtime.seconds_text(ns)
    assert unixtime.parse_seconds_ns(text) == ns and float(text) == pytest.approx(ns / 1e9, rel=1e-15, abs=1e-9)


def test_waterline_keeps_the_plane_pose_and_attitude():
    poses = np.array([pose(1.0, 2.0, 0.3, z=-0.4), np.full((4, 4), np.nan)])
    poses[0, :3, :3] = Rotation.from_euler("xyz", [0.05, -0.02, 0.3]).as_matrix()
    out = files.waterline(poses)
    assert out[0, 2, 3] == 0.0 and np.array_equal(np.delete(out[0].ravel(), 11), np.delete(poses[0].ravel(), 11))
    assert np.isnan(out[1, :2]).all() and poses[0, 2, 3] == -0.4


def test_tum_files_read_by_evo_give_our_ape_and_yaw_error(tmp_path):
    """evo, the field's trajectory evaluator, reads our TUM files as they are and, on a planar
    error (no height error), its APE and rotation error equal our horizontal APE and yaw error."""
    from evo.core import metrics as evo_metrics
    from evo.tools import file_interface

    n = 600
    truth = arc(n, radius=60.0, dtheta=0.005)
    i = np.arange(n)
    est = track(
        truth[:, 0, 3] + 1.5 * np.sin(i / 40.0), truth[:, 1, 3] + 0.8 * np.cos(i / 25.0), metrics.yaw_of(truth) + np.radians(3.0) * np.sin(i / 60.0)
    )
    est[:50] = np.nan  # before initialisation: no rows
    t = i / 10.0
    files.write_tum(tmp_path / "groundtruth.tum", t, truth)
    files.write_tum(tmp_path / "est.tum", t, est)
    reference = file_interface.read_tum_trajectory_file(str(tmp_path / "groundtruth.tum"))
    estimate = file_interface.read_tum_trajectory_file(str(tmp_path / "est.tum"))
    assert reference.num_poses == n and estimate.num_poses == n - 50
    reference.reduce_to_ids(np.arange(50, n))  # evo's sync.associate_trajectories does the same by stamps
    ours = metrics.estimator_metrics(run_record(truth, {"e": est}, t=t), "e", [])
    for relation, key, unit in ((evo_metrics.PoseRelation.translation_part, "ape", 1e-5), (evo_metrics.PoseRelation.rotation_angle_deg, "yaw", 1e-4)):
        ape = evo_metrics.APE(relation)
        ape.process_data((reference, estimate))
        theirs = ape.get_all_statistics()
        for stat in ("rmse", "mean", "median", "max"):
            assert ours[key][stat] == pytest.approx(theirs[stat], abs=unit), (key, stat)


def test_json_safe():
    tree = {
        "a": np.float64("nan"),
        "b": [float("inf"), -np.inf, np.float32(1.5)],
        "c": (np.int64(3), np.bool_(True)),
        "d": {"e": 2.5, "f": "x", "g": None, "h": 7},
    }
    out = metrics.json_safe(tree)
    assert out == {"a": None, "b": [None, None, 1.5], "c": [3, True], "d": {"e": 2.5, "f": "x", "g": None, "h": 7}}
    assert type(out["b"][2]) is float and type(out["c"][0]) is int and type(out["c"][1]) is bool
    json.dumps(out, allow_nan=False)


def test_compute_tree_is_json_safe():
    n = 30
    truth = line(n)
    est = truth.copy()
    est[:10] = np.nan
    fixes, *_ = monitor_case()
    rec = run_record(truth, {"e": est}, {"m": matcher_track(truth)}, fixes=fixes)
    from scenarios.score import vessel_log

    tree = metrics.compute(
        rec, win.find(fixes, [], 0.2), {"scenario": "x", "seed": np.int64(1)}, vessel_log.metrics(vessel_log.VesselLog(), 3.0, 0.1)
    )
    text = json.dumps(metrics.json_safe(tree), allow_nan=False)
    back = json.loads(text)
    assert back["vessel"]["outcome"] == "interrupted" and back["vessel"]["min_clearance_m"] is None
    assert back["estimators"]["e"]["available"] == pytest.approx(20 / 30)
    assert back["estimators"]["e"]["windows"]["nlos"]["max_error"] is None


def test_recorder_keeps_every_row_across_its_blocks():
    n = 9000  # past two 4096-row blocks
    truth = arc(n, radius=200.0, dtheta=0.001)
    rec = Recorder([], ["e"], MOUNT)
    for i in range(n):
        rec.scan(i / 10, truth[i], {}, {"e": truth[i] + 1.0})
    record = rec.finish([])
    assert np.array_equal(record.truth, truth) and np.array_equal(record.estimates["e"], truth + 1.0)
    assert np.array_equal(record.scan_t, np.arange(n) / 10)


def test_column_grows_after_it_was_read():
    column = Column(np.zeros(2))
    for i in range(5000):
        column.append(np.array([i, -i]))
    assert column.array().shape == (5000, 2)
    for i in range(5000, 9000):
        column.append(np.array([i, -i]))
    assert np.array_equal(column.array()[:, 0], np.arange(9000))


# ---------------------------------------------------------------- units and precision of metrics.json


def every_metric_tree() -> list[dict]:
    """A run's metrics tree with every node filled (windows, monitor, failures, vessel, movers) and a replay's."""
    from scenarios.pipeline.runner import RUN_NUMBERS
    from scenarios.replay import metrics as replay_metrics
    from scenarios.score import vessel_log

    n = 30
    truth = line(n)
    est = truth.copy()
    est[:10] = np.nan
    fixes, *_ = monitor_case()
    rec = run_record(truth, {"e": est}, {"m": matcher_track(truth)}, fixes=fixes)
    rec.failures = [
        {"component": "estimator", "id": "e", "stamp": 2.5, "reason": "x"},
        {"component": "matcher", "id": "m", "stamp": 2.6, "reason": "x"},
    ]
    run_info = {**dict.fromkeys(RUN_NUMBERS, 1.5), "duration_s": 2.0, "mover_points": {"median": 1.0, "p90": 2.0, "max": 3.0, "scans_with": 0.5}}
    windows = [win.Window(kind, 0.5, 1.0) for kind in win.KINDS]
    run = metrics.compute(rec, windows, run_info, vessel_log.metrics(vessel_log.VesselLog(), 3.0, 0.1))
    replay = replay_metrics.compute(rec, run_info, np.zeros(3))
    return [metrics.json_safe(run), metrics.json_safe(replay)]


def test_every_number_of_metrics_json_has_a_unit_and_a_precision_far_below_its_familys_tolerance():
    from scenarios.score import baseline, units

    paths = {path for tree in every_metric_tree() for path in baseline.flatten(tree)}
    assert len(paths) > 150
    for path in sorted(paths):
        quantity = units.quantity_of(path)
        assert quantity is not None, f"{path}: no unit in scenarios.score.units.QUANTITIES"
        family = metrics.family_of(path)
        if quantity.decimals is None or family.better == "none":
            continue
        if family.wall_clock:
            assert family.rel_tol >= 0.25 and quantity.decimals >= 1, path  # judged on medians of ms, Hz, MB: 0.1 is nothing
        else:
            assert 0.5 * 10.0**-quantity.decimals <= family.abs_tol / 100, (path, quantity, family.name)
    block = units.block()
    assert block["*.ape.*"] == "m" and block["*.yaw.*"] == "deg" and block["matchers.*.success"] == "share (0-1)"


def test_rounding_keeps_integers_flags_text_and_lists_and_rounds_floats_to_their_quantity():
    from scenarios.score import units

    tree = {
        "run": {"seed": 3, "t_start": 1974.7311226848155, "wall_s": 26.058935375, "failures": [{"stamp": 1.23456789}], "lanes": [["gicp"]]},
        "estimators": {
            "e": {"ape": {"rmse": 1.61300133691, "max": -0.00000001}, "yaw": {"p95": 1.7612345}, "failed": False, "available": 0.99868421}
        },
        "matchers": {"m": {"points": {"median": 10457.5}, "ms": {"p95": 46.4396536}, "hz": 33.6687991}},
        "vessel": {"outcome": "completed", "min_clearance_m": None},
    }
    out = units.rounded(tree)
    assert out["run"] == {"seed": 3, "t_start": 1974.731123, "wall_s": 26.059, "failures": [{"stamp": 1.23456789}], "lanes": [["gicp"]]}
    e = out["estimators"]["e"]
    assert e["ape"] == {"rmse": 1.613, "max": 0.0} and math.copysign(1.0, e["ape"]["max"]) == 1.0
    assert e["yaw"]["p95"] == 1.761 and e["failed"] is False and e["available"] == 0.9987
    assert out["matchers"]["m"] == {"points": {"median": 10457.5}, "ms": {"p95": 46.44}, "hz": 33.669}
    assert out["vessel"] == {"outcome": "completed", "min_clearance_m": None}
    assert json.dumps(out["estimators"]["e"]["ape"]) == '{"rmse": 1.613, "max": 0.0}'
