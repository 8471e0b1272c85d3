"""EKF against exact truth on synthetic streams: odometry only, GPS only, consistency, degeneracy."""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import pytest
from fusion_streams import StreamSpec, errors, generate, pose_at, run
from scipy.stats import chi2

import fusion
from fusion.geometry import compose
from fusion.observation import screen

EXACT_ODOMETRY = {"odom_floor_sigma_m": 0.0, "odom_floor_sigma_yaw_deg": 0.0, "odom_slip_frac": 0.0, "odom_slip_sigmas": 0.0}
"""The synthetic matcher's covariance is exact: no floor or slip allowance on top of it."""


def _initial(t_grid, poses, t=0.0):
    p = pose_at(t_grid, poses, t)
    return (float(p[0]), float(p[1]), math.degrees(p[2]))


def test_perfect_odometry_without_gps_reproduces_odometry():
    tiny = np.diag([1e-12, 1e-12, 1e-14])
    spec = StreamSpec(duration=40.0, odom_sigma=(0.0, 0.0, 0.0), odom_cov_scale=tiny, no_gps=True)
    events, t_grid, poses = generate(spec)
    ekf = fusion.create("ekf", initial_pose=_initial(t_grid, poses), initial_sigma=(1e-6, 1e-6), **EXACT_ODOMETRY)
    chain = np.asarray(pose_at(t_grid, poses, 0.0))
    for _kind, stamp, result in events:
        ekf.add_match(stamp, result)
        if result.ok:
            T = result.T
            chain = compose(chain, np.array([T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])]))
            est = ekf.pose
            assert np.hypot(est[0, 3] - chain[0], est[1, 3] - chain[1]) < 1e-4
            assert abs(math.atan2(est[1, 0], est[0, 0]) - chain[2]) < 1e-6
    truth = pose_at(t_grid, poses, events[-1][1])
    assert np.hypot(*(chain[:2] - truth[:2])) < 1e-6  # the odometry itself was perfect
    assert not [e for e in ekf.events if "first scan" not in e.reason]


def test_perfect_gps_is_followed_even_with_biased_odometry():
    spec = StreamSpec(duration=40.0, uere=1e-3, gps_noise=False, odom_corrupt=(1.1, 1.0))
    events, t_grid, poses = generate(spec)
    ekf = fusion.create("ekf", monitor="none", uere_m=1e-3, gps_correlation_s=0.0, initial_pose=_initial(t_grid, poses))
    out = run(ekf, events)
    err = errors(out, t_grid, poses)
    after_fix = np.array([kind == "fix" for kind, _, _ in events])
    late = out["stamp"] > 5.0
    assert np.abs(err[after_fix & late, :2]).max() < 0.01
    assert np.abs(err[late, :2]).max() < 0.05  # between fixes only 0.2 s of 10 % odometry bias


def _mean_nees(gps_tau: float, filter_tau: float, runs: int = 12) -> np.ndarray:
    """NEES of (x, y, yaw) averaged over Monte Carlo runs, per event."""
    nees = []
    for seed in range(runs):
        events, t_grid, poses = generate(StreamSpec(duration=60.0, gps_tau=gps_tau, seed=seed))
        rng = np.random.default_rng(100 + seed)
        x, y, yaw = _initial(t_grid, poses)
        start = (x + rng.normal(0, 1.0), y + rng.normal(0, 1.0), yaw + rng.normal(0, 5.0))
        ekf = fusion.create(
            "ekf",
            monitor="none",
            gps_correlation_s=filter_tau,
            gps_white_sigma_m=0.01,
            initial_pose=start,
            initial_sigma=(1.0, 5.0),
            **EXACT_ODOMETRY,
        )
        out = run(ekf, events)
        err = errors(out, t_grid, poses)
        nees.append(np.einsum("ni,nij,nj->n", err, np.linalg.inv(out["cov"]), err))
    return np.mean(nees, axis=0)


@pytest.mark.parametrize("gps_tau", [0.0, 30.0], ids=["white-gps", "correlated-gps"])
def test_nees_is_consistent(gps_tau):
    runs = 12
    mean_over_runs = _mean_nees(gps_tau, gps_tau, runs)
    lo, hi = chi2.ppf(0.025, 3 * runs) / runs, chi2.ppf(0.975, 3 * runs) / runs
    assert lo < mean_over_runs.mean() < hi
    assert np.mean((mean_over_runs > lo) & (mean_over_runs < hi)) > 0.7


def test_treating_correlated_gps_as_independent_is_overconfident():
    runs = 6
    assert _mean_nees(30.0, 0.0, runs).mean() > 5.0 * chi2.ppf(0.975, 3 * runs) / runs


def _gps_error(events, t_grid, poses):
    """(stamp, antenna error east, north) of every fix with a position."""
    return np.array([(t, *f.truth.error[:2]) for k, t, f in events if k == "fix" and f.quality])


@pytest.mark.parametrize("mount_yaw_deg", [0.0, 90.0])
def test_degenerate_odometry_leans_on_gps_along_that_axis(mount_yaw_deg):
    # A matcher in a straight canal: the forward motion is unobserved (it reports none of it) and
    # says so with a huge forward variance in its own (lidar) frame; sideways and yaw are precise.
    mount = np.eye(4)
    c, s = math.cos(math.radians(mount_yaw_deg)), math.sin(math.radians(mount_yaw_deg))
    mount[:2, :2] = [[c, -s], [s, c]]
    mount[2, 3] = 1.8
    # forward variance in base_link; the stream reports it in the lidar frame (lidar -y when it looks left)
    degenerate = np.diag([25.0, 0.01**2, math.radians(0.05) ** 2])
    confident = np.diag([0.01**2, 0.01**2, math.radians(0.05) ** 2])
    results = {}
    for name, cov in (("degenerate", degenerate), ("confident", confident)):
        # white GPS noise (and the filter told so): a question of geometry, not of noise colour
        spec = StreamSpec(
            duration=60.0, turn_amp_dps=0.0, odom_sigma=(0, 0, 0), odom_cov_scale=cov, odom_corrupt=(0.0, 1.0), mount=mount, gps_tau=0.0, seed=3
        )
        events, t_grid, poses = generate(spec)
        ekf = fusion.create(
            "ekf", monitor="none", initial_pose=_initial(t_grid, poses), gps_correlation_s=0.0, mount=[list(r) for r in mount], **EXACT_ODOMETRY
        )
        out = run(ekf, events)
        err = errors(out, t_grid, poses)
        yaw = pose_at(t_grid, poses, 0.0)[2]
        along = err[:, 0] * math.cos(yaw) + err[:, 1] * math.sin(yaw)
        across = -err[:, 0] * math.sin(yaw) + err[:, 1] * math.cos(yaw)
        late = out["stamp"] > 20.0
        results[name] = (np.sqrt(np.mean(along[late] ** 2)), np.sqrt(np.mean(across[late] ** 2)), out["cov"][-1])
    gps = _gps_error(events, t_grid, poses)
    gps = gps[gps[:, 0] > 20.0]
    gps_along = np.sqrt(np.mean((gps[:, 1] * math.cos(yaw) + gps[:, 2] * math.sin(yaw)) ** 2))
    gps_across = np.sqrt(np.mean((-gps[:, 1] * math.sin(yaw) + gps[:, 2] * math.cos(yaw)) ** 2))
    along, across, cov = results["degenerate"]
    assert along < 1.5 * gps_along + 0.3  # GPS carries the along-canal position...
    assert across < 0.3 * gps_across  # ...the odometry keeps the cross-canal position far tighter
    u = np.array([math.cos(yaw), math.sin(yaw)])
    v = np.array([-math.sin(yaw), math.cos(yaw)])
    # uncertainty is along the canal (the motion model also averages GPS along it, bounding the ratio)
    assert u @ cov[:2, :2] @ u > 2.5 * (v @ cov[:2, :2] @ v)
    assert results["confident"][0] > 10.0  # trusting the slipping matcher loses the boat


def test_coasts_with_growing_covariance_when_the_matcher_always_fails():
    spec = StreamSpec(duration=30.0, failing_matcher=True, no_gps=False)
    events, t_grid, poses = generate(spec)
    ekf = fusion.create("ekf", monitor="none")
    out = run(ekf, events)
    assert ekf.initialized  # from the GPS course alone
    err = errors(out, t_grid, poses)
    late = np.isfinite(err[:, 0]) & (out["stamp"] > 15)
    gps = _gps_error(events, t_grid, poses)
    gps_rms = np.sqrt(np.mean(np.sum(gps[gps[:, 0] > 15, 1:] ** 2, axis=1)))
    assert np.sqrt(np.mean(np.sum(err[late, :2] ** 2, axis=1))) < 1.5 * gps_rms + 0.5
    reasons = {e.reason for e in ekf.events}
    assert any("always fails" in r for r in reasons)


def test_coasting_through_a_matcher_outage_without_gps():
    spec = StreamSpec(duration=30.0, no_gps=True, turn_amp_dps=0.0)
    events, t_grid, poses = generate(spec)
    ekf = fusion.create("ekf", initial_pose=_initial(t_grid, poses), initial_sigma=(0.1, 0.5))
    traces = []
    for _kind, stamp, result in events:
        if 10.0 <= stamp < 13.0:
            ekf.add_match(stamp, type(result).failure("blinded"))
            traces.append(np.trace(ekf.cov[:2, :2]))
        else:
            ekf.add_match(stamp, result)
    assert np.all(np.diff(traces) > 0)  # uncertainty grows while coasting
    truth = pose_at(t_grid, poses, events[-1][1])
    assert np.hypot(ekf.pose[0, 3] - truth[0], ekf.pose[1, 3] - truth[1]) < 3.0


def test_a_matcher_slipping_with_a_tight_covariance_is_caught_by_the_slip_test():
    # As gicp under a charles_river bridge: from t = 20 s every match reports no forward motion at
    # +-1 cm. The slip test makes the forward direction unobserved, so GPS and the motion model carry it.
    confident = np.diag([0.01**2, 0.01**2, math.radians(0.05) ** 2])
    spec = StreamSpec(
        duration=60.0,
        turn_amp_dps=0.0,
        odom_sigma=(0, 0, 0),
        odom_cov_scale=confident,
        odom_corrupt=(0.0, 1.0),
        corrupt_from_s=20.0,
        gps_tau=0.0,
        seed=3,
    )
    events, t_grid, poses = generate(spec)
    gps = _gps_error(events, t_grid, poses)
    gps_rms = np.sqrt(np.mean(np.sum(gps[gps[:, 0] > 20.0, 1:] ** 2, axis=1)))
    rms = {}
    for name, slip_sigmas in (("slip test", 3.0), ("no slip test", 0.0)):
        ekf = fusion.create(
            "ekf", monitor="none", initial_pose=_initial(t_grid, poses), gps_correlation_s=0.0, odom_slip_frac=0.0, odom_slip_sigmas=slip_sigmas
        )
        out = run(ekf, events)
        err = errors(out, t_grid, poses)[out["stamp"] > 20.0]
        rms[name] = np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1)))
    assert rms["slip test"] < gps_rms
    assert rms["no slip test"] > 3.0 * gps_rms  # believing it loses the boat


def test_the_gps_bias_follows_the_satellite_geometry_at_once():
    """The receiver's error is its range errors (slow) mapped through the geometry (at once): when HDOP falls from 15 at a
    deck's edge to 1, the bias's variance is HDOP 1's level at the next fix, not 225 times it relaxing over 30 s, and the
    ratio of the bias's sd before and after is the ratio of the error levels (docs/models.md, a deck's-edge bias)."""
    spec = StreamSpec(duration=40.0, seed=3)
    events, t_grid, poses = generate(spec)
    edge = [(k, s, replace(f, hdop=15.0)) if k == "fix" and 20.0 <= s < 25.0 else (k, s, f) for k, s, f in events]
    # every fix refused (HDOP above 0.5), so no update hides what the level does; the odometry carries the pose
    est = fusion.create("ekf", matcher="m", monitor="hdop", monitor_params={"max_hdop": 0.5}, initial_pose=tuple(_initial(t_grid, poses)))
    p = est.params
    level = lambda hdop: p.bias_variance((p.uere_m * hdop) ** 2 / 2.0)
    sd = {}
    for kind, stamp, payload in edge:
        run(est, [(kind, stamp, payload)])
        if kind == "fix" and stamp < 25.2:
            sd[round(stamp, 1)] = math.sqrt(est.P[6, 6])  # the bias's east sd (state BX)
    last_edge, first_open = max(t for t in sd if t < 25.0), min(t for t in sd if t >= 25.0)
    assert sd[first_open] / sd[last_edge] == pytest.approx(math.sqrt(level(1.0) / level(15.0)), rel=0.02)
    assert sd[first_open] ** 2 == pytest.approx(level(1.0), rel=0.05)


@pytest.mark.parametrize("kind", ["ekf", "pf"])
def test_a_fix_trusted_with_an_allowance_weighs_in_as_a_noisier_one(kind):
    """A monitor's allowance (fusion.Verdict.allowance_m) adds to the fix's measurement noise: after 20 s on a clean
    stream, a fix 3 m east of the truth moves the estimate east by less with a 3 m allowance than without one, and by almost
    nothing with 1 km."""
    from fusion.monitors.base import Monitor

    class Allowing(Monitor):
        name = "allowing"

        def __init__(self, allowance_m: float) -> None:
            self.allowance_m = allowance_m

        def check(self, obs, ctx):
            return fusion.Verdict(True, 0.0, "test", rule="test.allow" if self.allowance_m else "", allowance_m=self.allowance_m)

    events, t_grid, poses = generate(StreamSpec(duration=20.0, gps_noise=False, seed=3))
    fix = next(p for k, _, p in reversed(events) if k == "fix")
    moved = {}
    for allowance in (0.0, 1.0, 3.0, 1000.0):
        est = fusion.create(kind, monitor="none", initial_pose=_initial(t_grid, poses), **({"seed": 0} if kind == "pf" else {}))
        est.monitor = Allowing(allowance)
        run(est, events)
        before = est.pose[0, 3]
        est.add_fix(replace(fix, stamp=events[-1][1] + 0.01, enu=np.asarray(fix.enu) + [3.0, 0.0, 0.0]))
        moved[allowance] = est.pose[0, 3] - before
    jitter = 0.01 if kind == "ekf" else 0.1  # the pf's cloud moves a little with any update (its resampling)
    assert moved[0.0] > moved[3.0] > 0.0 and abs(moved[1000.0]) < jitter * moved[0.0]
    if kind == "ekf":  # Gaussian: the pull falls with every allowance (the pf's Student-t pulls hardest at a scale near the offset)
        assert moved[0.0] > moved[1.0] > moved[3.0]


def _yaw_p95_deg(spec: StreamSpec, **params) -> float:
    events, t_grid, poses = generate(spec)
    out = run(fusion.create("ekf", matcher="m", **params), events)
    settled = out["stamp"] > 20.0
    return float(np.degrees(np.percentile(np.abs(errors(out, t_grid, poses)[settled, 2]), 95)))


@pytest.mark.parametrize("seed", range(3))
def test_the_receivers_velocity_gives_the_heading(seed):
    """Exact velocities over ground (RMC/VTG) on a weaving track: with the matcher's steps the heading's p95 falls from
    the fixes' track (6-8 deg) to about 2 deg; with the matcher failing throughout, from 20-40 deg to under 6 (the
    sideslip decays with the hull's sway time constant, so the velocity's share across the track goes to the heading)."""
    with_odometry = StreamSpec(duration=90.0, report_velocity=True, seed=seed)
    assert _yaw_p95_deg(with_odometry) < 3.0 < _yaw_p95_deg(with_odometry, gps_velocity_sigma_mps=None)
    no_odometry = replace(with_odometry, failing_matcher=True)
    assert _yaw_p95_deg(no_odometry) < 6.0 < _yaw_p95_deg(no_odometry, gps_velocity_sigma_mps=None)


def test_a_velocity_off_by_metres_a_second_or_at_a_decks_edge_is_not_used():
    """A velocity turned 90 deg off the track (a reflected satellite's path rate of metres a second) fails the gate; one
    at HDOP 8 is not used whatever it says; neither moves the state, and the true one is used."""
    spec = StreamSpec(duration=40.0, report_velocity=True, seed=1)
    events, _, _ = generate(spec)
    ekf = fusion.create("ekf", matcher="m")
    run(ekf, [e for e in events if e[1] < 30.0])
    fix = next(e[2] for e in events if e[0] == "fix" and e[1] >= 30.0)
    turned = replace(fix, course_deg=(fix.course_deg + 90.0) % 360.0)
    deck_edge = replace(fix, hdop=8.0, course_deg=(fix.course_deg + 30.0) % 360.0)
    for bad, why in ((turned, "velocity refused: innovation"), (deck_edge, "velocity not used: HDOP 8.0 > 2.5")):
        probe = copy.deepcopy(ekf)
        state = probe.x.copy()
        assert probe._use_velocity(screen(bad, probe.params.uere_m, False)[0]).startswith(why)
        np.testing.assert_array_equal(probe.x, state)
    assert copy.deepcopy(ekf)._use_velocity(screen(fix, ekf.params.uere_m, False)[0]) == ""


def _pitching(events: list[tuple], mount: np.ndarray, rate_dps: float) -> list[tuple]:
    """The matches of `events` with a steady pitch rate added to each step (a matcher's drift in a canal)."""
    out = []
    for kind, stamp, result in events:
        if kind == "match" and result.ok:
            angle = math.radians(rate_dps) * 0.1
            pitch = np.eye(4)
            pitch[[0, 0, 2, 2], [0, 2, 0, 2]] = [math.cos(angle), math.sin(angle), -math.sin(angle), math.cos(angle)]
            result = replace(result, T=result.T @ np.linalg.inv(mount) @ pitch @ mount)
        out.append((kind, stamp, result))
    return out


@pytest.mark.parametrize("seed", range(3))
def test_a_matchers_pitch_drift_does_not_move_the_speed(seed):
    """A floating hull's tilt rates average to zero over a few wave periods, so a steady pitch rate in the matches is the
    matcher's drift (gicp in rough_water's canal, seed 1: -0.8 deg/s for 25 s) and must not swing the antenna, 1.3 m up
    its mast, in the velocity update: taken as the hull's, 0.8 deg/s moves the speed 1.8 cm/s ahead of the Doppler's
    (1.3 m x 0.014 rad/s). Exact velocities over ground; the forward speed's mean error from 40 s on stays within 3 mm/s."""
    spec = StreamSpec(duration=90.0, report_velocity=True, seed=seed)
    events, _, _ = generate(spec)
    drifting = _pitching(events, spec.mount, rate_dps=-0.8)
    ekf = fusion.create("ekf", matcher="m")
    speed_error = []
    for kind, stamp, payload in drifting:
        ekf.add_match(stamp, payload) if kind == "match" else ekf.add_fix(payload)
        if stamp > 40.0 and kind == "fix":
            truth = spec.speed * (1.0 + 0.2 * math.sin(2 * math.pi * stamp / 40.0))
            speed_error.append(ekf.x[3] - truth)
    assert abs(float(np.mean(speed_error))) < 0.003
