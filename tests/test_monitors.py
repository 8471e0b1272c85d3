"""GPS integrity monitors on synthetic streams with labelled faults: multipath jumps under low HDOP
and a receiver that smooths a wrong estimate back after a blackout."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fusion_streams import Fault, StreamSpec, errors, generate, run
from hypothesis import given, settings
from hypothesis import strategies as st

import fusion
from fusion import monitors
from fusion.monitors import FixContext
from fusion.monitors.track_noise import TrackNoise
from fusion.observation import FixObservation
from fusion.odometry import OdometryTrack
from sim.gnss_fix import SatelliteReport

MULTIPATH = Fault(30.0, 40.0, (15.0, -8.0))
BLACKOUT = Fault(50.0, 65.0, (0.0, 0.0), blackout=True)
REACQUIRED = Fault(65.0, 100.0, (18.0, 10.0), tau=10.0)
JUMP = Fault(110.0, 112.0, (0.0, 20.0))
FAULTS = [MULTIPATH, BLACKOUT, REACQUIRED, JUMP]
NO_SLIP = {"odom_slip_frac": 0.0, "odom_slip_sigmas": 0.0}
"""The synthetic matcher does not slip along the motion: no allowance for it."""


@pytest.fixture(scope="module")
def faulty_stream():
    return generate(StreamSpec(duration=130.0, faults=FAULTS, seed=7))


def _labelled(out):
    """(stamp, trusted, statistic, true horizontal error) of every fix with a position."""
    rows = [(t, v.trusted, v.statistic, float(np.hypot(*f.truth.error[:2]))) for t, v, f in out["verdicts"] if f.quality]
    return np.array(rows, dtype=float)


def _in(fault, t):
    return (t >= fault.start) & (t < fault.end)


def test_hdop_misses_multipath_that_consistency_catches(faulty_stream):
    events, t_grid, poses = faulty_stream
    rows = {}
    for name in ("hdop", "consistency", "combined"):
        out = run(fusion.create("ekf", monitor=name, **NO_SLIP), events)
        rows[name] = (_labelled(out), errors(out, t_grid, poses), out["stamp"])
    hdop = rows["hdop"][0]
    assert hdop[_in(MULTIPATH, hdop[:, 0]), 1].all()  # HDOP stays low: every multipath fix is trusted
    for name in ("consistency", "combined"):
        lab, err, stamps = rows[name]
        t, trusted, err_fix = lab[:, 0], lab[:, 1].astype(bool), lab[:, 3]
        jumps = _in(MULTIPATH, t) | _in(JUMP, t)
        assert np.mean(~trusted[jumps]) > 0.95
        assert not trusted[_in(REACQUIRED, t) & (err_fix > 8.0)].any()  # the smoothed wrong estimate
        clean = (t > 15.0) & ~(jumps | _in(BLACKOUT, t) | _in(REACQUIRED, t)) & (err_fix < 5.0)
        assert np.mean(~trusted[clean]) < 0.05
        late = np.isfinite(err[:, 0]) & (stamps > 15.0)
        assert np.abs(err[late, :2]).max() < 4.0  # the fused estimate rides through all of it
    hdop_err = rows["hdop"][1]
    assert np.abs(hdop_err[np.isfinite(hdop_err[:, 0]), :2]).max() > 6.0


def test_baselines_err_by_metres_through_the_faults(faulty_stream):
    events, t_grid, poses = faulty_stream
    for name in ("gps_only", "hdop_switch"):
        out = run(fusion.create(name, **({} if name == "gps_only" else NO_SLIP)), events)
        err = errors(out, t_grid, poses)
        during = _in(REACQUIRED, out["stamp"]) & (out["stamp"] < 75.0)
        assert np.hypot(err[during, 0], err[during, 1]).max() > 10.0


def test_nis_flags_jumps_against_the_filter(faulty_stream):
    events, _, _ = faulty_stream
    lab = _labelled(run(fusion.create("ekf", monitor="nis", **NO_SLIP), events))
    t, trusted = lab[:, 0], lab[:, 1].astype(bool)
    assert np.mean(~trusted[_in(MULTIPATH, t)]) > 0.9
    assert np.all(lab[:, 2][np.isfinite(lab[:, 2])] >= 0.0)


@pytest.mark.parametrize("name, auc_min", [("nis", 0.85), ("consistency", 0.95), ("combined", 0.95)])
def test_statistic_ranks_faulty_fixes_above_clean_ones(faulty_stream, name, auc_min):
    # nis is weaker: once the slowly converging post-blackout fix squeezes under its gate, the
    # filter's bias state absorbs the rest; the consistency guard is there for exactly that
    events, _, _ = faulty_stream
    lab = _labelled(run(fusion.create("ekf", monitor=name, **NO_SLIP), events))
    ok = lab[:, 0] > 15.0
    stat = np.nan_to_num(lab[ok, 2], nan=-1.0)
    faulty = lab[ok, 3] > 8.0
    # probability that a faulty fix scores above a clean one (area under the ROC curve)
    auc = np.mean(stat[faulty][:, None] > stat[~faulty][None, :])
    assert auc > auc_min


def _obs(t, xy, sigma=1.0):
    return FixObservation(stamp=t, xy=np.asarray(xy, float), cov=np.eye(2) * sigma**2, z=0.0, z_var=1.0, quality=1, hdop=1.0)


@settings(max_examples=25, deadline=None)
@given(bx=st.floats(-50, 50), by=st.floats(-50, 50), yaw=st.floats(-3.1, 3.1))
def test_window_test_cancels_a_constant_bias(bx, by, yaw):
    # A straight run at 2 m/s along `yaw`; GPS carries a constant bias from the start: the
    # displacement tests see nothing, whatever the bias.
    track = OdometryTrack()
    stamps = np.arange(0.0, 20.0, 0.1)
    for t in stamps:
        track.add(float(t), np.array([0.2, 0.0, 0.0]), np.diag([1e-4, 1e-4, 1e-6]))
    unbiased, biased = monitors.create("consistency", startup_guard=True), monitors.create("consistency", startup_guard=True)
    ctx = FixContext(predicted=None, yaw=yaw, yaw_var=1e-6, lever=np.zeros(2), odometry=track)
    direction = np.array([math.cos(yaw), math.sin(yaw)])
    for t in np.arange(0.0, 19.0, 0.2):
        truth = 2.0 * t * direction
        verdicts = []
        for mon, xy in ((unbiased, truth), (biased, truth + [bx, by])):
            verdicts.append(mon.check(_obs(float(t), xy), ctx))
            mon.commit(_obs(float(t), xy), verdicts[-1])
        # start-up guard: its window test can be made from half a window (1 s) after the first fix, and five (guard_n)
        # consecutive passes at 5 Hz end it at 2 s; then trusted
        assert verdicts[0].trusted == verdicts[1].trusted == (t >= 2.0)
        assert verdicts[0].rule == verdicts[1].rule == ("" if t >= 2.0 else "consistency.guard")  # the rule that refused it
        assert np.allclose(verdicts[0].statistic, verdicts[1].statistic, equal_nan=True, atol=1e-6)


def test_without_the_start_up_guard_the_first_fixes_are_judged_and_an_outage_still_starts_the_guard():
    """startup_guard=False (the default): on a straight run at 2 m/s with fixes on the truth, the fixes are trusted from the first one
    (no window or reference to test yet, then both pass); a 3 s gap in the fixes still starts the guard, and so does the
    first fix of a host that started from a given pose (FixContext.own_start). The guard's evidence is the window test,
    which can be made from half a window (1 s) after the gap's first fix on: five (guard_n) consistent fixes at 5 Hz then
    end it, about 2 s after the gap (the reference carried over the gap is no evidence alone). With guard_s = 5 (a fixed
    wait) it lasts 5 s."""
    track = OdometryTrack()
    for t in np.arange(0.0, 30.0, 0.1):
        track.add(float(t), np.array([0.2, 0.0, 0.0]), np.diag([1e-4, 1e-4, 1e-6]))
    ctx = FixContext(predicted=None, yaw=0.0, yaw_var=1e-6, lever=np.zeros(2), odometry=track)
    mon = monitors.create("consistency", startup_guard=False)
    verdicts = {}
    for t in [*np.arange(0.0, 10.0, 0.2), *np.arange(13.0, 25.0, 0.2)]:
        obs = _obs(float(t), [2.0 * t, 0.0])
        verdicts[round(float(t), 1)] = v = mon.check(obs, ctx)
        mon.commit(obs, v)
    assert all(v.trusted for t, v in verdicts.items() if t < 10.0)
    assert all(not v.trusted and v.rule == "consistency.guard" for t, v in verdicts.items() if 13.0 <= t < 15.1)
    assert all(v.trusted for t, v in verdicts.items() if t >= 15.1)
    # a host that started from a given pose holds a position of its own from the first fix: guarded from there
    own = monitors.create("consistency", startup_guard=False)
    own_ctx = FixContext(predicted=None, yaw=0.0, yaw_var=1e-6, lever=np.zeros(2), odometry=track, own_start=True)
    first = []
    for t in np.arange(0.0, 8.0, 0.2):
        obs = _obs(float(t), [2.0 * t, 0.0])
        first.append((round(float(t), 1), v := own.check(obs, own_ctx)))
        own.commit(obs, v)
    assert all(not v.trusted for t, v in first if t < 1.9) and all(v.trusted for t, v in first if t >= 1.9)
    waited = monitors.create("consistency", startup_guard=False, guard_s=5.0)
    for t in np.arange(0.0, 8.0, 0.2):
        obs = _obs(float(t), [2.0 * t, 0.0])
        assert (v := waited.check(obs, own_ctx)).trusted == (t >= 4.9)
        waited.commit(obs, v)


def test_registry_validates_names_and_parameters():
    assert set(monitors.available()) == {"hdop", "nis", "consistency", "cn0", "combined", "combined_cn0", "combined_shadow", "none", "shadow"}
    with pytest.raises(ValueError, match="unknown monitor 'raim'"):
        monitors.create("raim")
    with pytest.raises(ValueError, match="monitor 'hdop': max_hdop: Input should be greater than 0"):
        monitors.create("hdop", max_hdop=-1)
    with pytest.raises(ValueError, match="'window'"):
        monitors.create("consistency", window=3)
    with pytest.raises(ValueError, match="non-member 'hdop'"):
        monitors.create("combined", member_params={"hdop": {}})
    with pytest.raises(ValueError, match="'members'"):
        monitors.create("combined", members=["combined"])
    mon = monitors.create("combined", members=["hdop", "consistency"], member_params={"hdop": {"max_hdop": 1.5}})
    assert [m.name for m in mon.members] == ["hdop", "consistency"]


def _along_a_wall(unobserved: float = 1e6, prior_mps: float = 2.0, until: float = 40.0) -> OdometryTrack:
    """A straight run east at 2 m/s whose matches leave the along-track direction unobserved (a degenerate match along a
    quay keeps a prior of its own there, prior_mps: the step is right when that is 2, its variance 1e6 m^2)."""
    track = OdometryTrack()
    for t in np.arange(0.0, until, 0.1):
        track.add(float(t), np.array([0.1 * prior_mps, 0.0, 0.0]), np.diag([unobserved, 1e-4, 1e-6]))
    return track


def _feed(
    mon,
    track: OdometryTrack,
    error_of,
    suspect_of=lambda t: False,
    velocity: np.ndarray | None = None,
    until: float = 39.0,
    velocity_cov: np.ndarray | None = None,
    correlation_s: float = 30.0,
    sigma: float = 0.5,
    doppler: bool = False,
) -> list:
    """Fixes at 5 Hz on the true track plus error_of(t) metres east; suspect_of(t) fixes are refused on their own
    evidence first (as a C/N0 monitor would); every fix goes through check and commit; velocity: the host filter's (None:
    a host without one), velocity_cov its covariance; correlation_s: the receiver's error time constant the host gives;
    sigma: each fix's per-axis sigma; doppler: each fix reports the vessel's true velocity over ground (RMC 2 m/s, course
    090). Returns (t, verdict) pairs."""
    ctx = FixContext(
        predicted=None,
        yaw=0.0,
        yaw_var=1e-6,
        lever=np.zeros(2),
        odometry=track,
        correlation_s=correlation_s,
        velocity=velocity,
        velocity_cov=velocity_cov,
    )
    out = []
    for t in np.arange(0.0, until, 0.2):
        obs = _obs(float(t), [2.0 * t + error_of(t), 0.0], sigma=sigma)
        if doppler:
            obs = dataclasses.replace(obs, speed_mps=2.0, course_deg=90.0)
        verdict = mon.check(obs, ctx)
        if suspect_of(t) and verdict.trusted:
            verdict = fusion.Verdict(False, verdict.statistic, "suspect", on_its_own=True, steady=verdict.steady)
        mon.commit(obs, verdict)
        out.append((float(t), verdict))
    return out


def test_a_receivers_ramp_along_an_unobserved_direction_is_refused():
    """quickstart at 1762 s: beside a quay gicp leaves the along-wall direction unobserved, and a reflected signal,
    smoothed by the receiver's filter, ramps the fixes along it at 3 m/s after every earlier fix was refused on C/N0.
    The window test now takes those refused fixes as anchors and bounds the unobserved direction by the
    constant-velocity extrapolation, so the ramp is refused from its first metres; the plateau it reaches stays refused."""
    ramp = lambda t: 0.0 if t < 20.0 else min(3.0 * (t - 20.0), 40.0)
    verdicts = _feed(monitors.create("consistency"), _along_a_wall(), ramp, suspect_of=lambda t: 12.0 <= t < 20.0)
    off = [(t, v) for t, v in verdicts if ramp(t) > 3.0]
    assert off and not any(v.trusted for _, v in off)
    assert not any(v.steady for t, v in verdicts if 21.5 <= t < 33.0)  # the ramp never counts towards a re-lock


QUAY_ERROR_M = [0.3, 0.6, 0.3, 0.4, 0.4, 0.3, 0.8, 2.3, 5.1, 9.7, 15.7, 23.9, 32.8, 36.9, 39.1, 42.0, 44.2, 46.0, 46.8, 47.1]
QUAY_ERROR_M += [46.3, 45.1, 44.3, 42.5, 39.4, 34.4, 28.4, 18.6, 9.8, 2.0, 2.1, 3.0, 4.2, 5.4, 5.8, 5.2, 4.6, 3.2, 1.2, 0.4]
QUAY_NLOS = [False, False] + [True] * 19 + [False] * 19
"""The receiver's error at 1 s steps beside the quickstart's quays (seed 0, 1755.1-1794.1 s: gps.csv's err_h and
nlos_used): a reflected signal smoothed into a ramp to 47 m, then the filter's walk-back once the reflection ends."""


def test_a_receivers_walk_back_from_a_refused_ramp_is_refused_until_it_has_settled():
    """quickstart at 1782.1 s: after the ramp's fixes were refused, the reference's along-quay sigma had grown to 5.5 m,
    so a fix still 18.5 m off, walking back at 10 m/s, passed it at 3.4 sigma and the ekf followed it (4.4 -> 19.4 m
    off). The window test against the fix a window earlier, refused as it was, sees the walk-back move against the
    odometry."""
    error = lambda t: 0.0 if t < 20.0 else float(np.interp(t - 20.0, np.arange(len(QUAY_ERROR_M)), QUAY_ERROR_M))
    suspect = lambda t: 20.0 <= t < 60.0 and QUAY_NLOS[min(int(round(t - 20.0)), len(QUAY_NLOS) - 1)]
    verdicts = _feed(monitors.create("consistency"), _along_a_wall(until=71.0), error, suspect, np.array([2.0, 0.0]), until=70.0)
    assert not any(v.trusted for t, v in verdicts if error(t) > 6.0)
    assert any(v.trusted for t, v in verdicts if t > 60.0)  # back on GPS once the fixes move with the vessel again


def test_a_walk_back_after_a_long_refused_stretch_meets_the_tighter_gate():
    """quickstart seed 4 at 1771.9 s: after 20 s of refused fixes beside a quay (a reflected ramp to 48 m), the receiver
    walked back at 1-1.5 m/s along the quay, where the host's speed is doubted: the window test saw 3 m in 2 s within its
    gate (13.5 < 13.8), the reference, carried 20 s along the quay, passed 25 m at its 11 m sigma, and the ekf went 5.5 ->
    29.9 m off. After refused_s of refusals both tests take the guard's gate until a fix passes: the plateau and the
    walk-back stay refused (with the verdict's gate alone, refused_s never reached, a fix 45 m off passes at 13.7 against
    13.8), and the good fixes after it are trusted within walk_window_s (4 s: steady against the receiver's own velocity
    over that long, as the next test needs)."""
    ramp = lambda t: float(np.interp(t, [10.0, 25.0, 32.0, 62.0], [0.0, 45.0, 45.0, 0.0]))
    doubted = {"velocity": np.array([2.0, 0.0]), "velocity_cov": np.diag([0.45**2, 0.1**2]), "until": 75.0}
    track = _along_a_wall(until=76.0)
    before = _feed(monitors.create("consistency", refused_s=1e9), track, ramp, **doubted)
    assert any(v.trusted for t, v in before if ramp(t) > 6.0)
    verdicts = _feed(monitors.create("consistency"), track, ramp, **doubted)
    assert not any(v.trusted for t, v in verdicts if ramp(t) > 6.0)
    assert all(v.trusted for t, v in verdicts if t >= 62.0 + 4.0)


def test_a_walk_back_that_overshoots_is_refused_through_its_turn():
    """quickstart seed 4 at 1785.7 s: after 33 s of refused fixes beside a quay the receiver's filter walked back from a
    reflected ramp, overshot to 10.3 m on the other side and turned there: over the 2 s window its track stood still
    against the vessel (4.1 under the guard's gate), the reference was 6 m uncertain along the quay, and the ekf went 0.1
    -> 8.8 m off. Since the receiver must also have moved with its own velocity over ground (or the odometry) against
    every fix of the last walk_window_s, the turn stays refused; the good fixes after it are trusted within that long."""

    def overshoot(t: float) -> float:  # a ramp to 45 m, its plateau, a walk-back, a turn 10 m beyond (parabolic, 11 s)
        if t < 55.0:
            return float(np.interp(t, [10.0, 25.0, 32.0, 55.0], [0.0, 45.0, 45.0, 0.0]))
        return -10.0 + 10.0 * ((t - 60.5) / 5.5) ** 2 if t < 66.0 else 0.0

    doubted = {"velocity": np.array([2.0, 0.0]), "velocity_cov": np.diag([0.45**2, 0.1**2]), "until": 80.0}
    one_lag = _feed(monitors.create("consistency", walk_window_s=0.01), _along_a_wall(until=81.0), overshoot, **doubted)
    assert any(v.trusted for t, v in one_lag if abs(overshoot(t)) > 5.0)
    verdicts = _feed(monitors.create("consistency"), _along_a_wall(until=81.0), overshoot, **doubted)
    assert not any(v.trusted for t, v in verdicts if abs(overshoot(t)) > 5.0)
    assert {v.rule for t, v in verdicts if 60.0 <= t <= 61.0} == {"consistency.walk"}  # the turn: the walk test's refusal
    assert all(v.trusted for t, v in verdicts if t >= 66.0 + 4.0)


def test_the_track_noise_is_the_receivers_clean_spread_whatever_a_faults_onset_adds():
    """A receiver whose output error walks 0.1 m/sqrt(s) east and 0.05 north about its exact Doppler, 5 Hz: the learned
    spread over 1 s is (0.1, 0.05) m within the sampling error of its 600 overlapping residuals (15%), also with the
    first second of a 6 m/s ramp trusted among them (the host trusts a fault's onset before its monitor sees it); and
    nothing before 50 residuals."""
    rng = np.random.default_rng(7)
    wander = np.cumsum(np.sqrt(0.2) * np.array([0.1, 0.05]) * rng.standard_normal((700, 2)), axis=0)
    noise, kept = TrackNoise(), []
    for k in range(700):
        t = 0.2 * k
        ramp = 6.0 * (t - 100.0) if 100.0 <= t < 101.0 else 0.0
        obs = dataclasses.replace(_obs(t, [2.0 * t + wander[k, 0] + ramp, wander[k, 1]]), speed_mps=2.0, course_deg=90.0)
        kept = [*kept, obs][-10:] if ramp < 6.0 else [obs]  # the ramp's end refused: the trusted run starts again
        noise.learn(kept)
        if k == 50:
            assert noise.sigma_m is None
    assert noise.sigma_m == pytest.approx([0.1, 0.05], rel=0.15)
    assert noise.noise_of(noise.sigma_m, kept[0], kept[-1]) == pytest.approx(np.diag(noise.sigma_m**2) * (kept[-1].stamp - kept[0].stamp))


def test_a_walk_backs_tail_is_judged_on_the_receivers_own_clean_track():
    """The full quickstart, seed 0, 1790.0 s: the receiver's filter walked back from a reflection, overshot to 5.8 m
    and turned there; against the host's error model (HDOP x UERE, correlated over 30 s: 0.83 m per axis over 4 s) its
    1.8 m against the Doppler over 4 s passed the walk test at 4.5 under the gate's 4.6, and the ekf went 2.2 -> 4.5 m
    off. The receiver's own clean track, learned from the fixes the host trusted (here a random walk of 0.1 m/sqrt(s),
    Doppler exact), strays 0.2 m in 4 s: the turn stays refused, and the good fixes after it are trusted."""
    wander = np.cumsum(0.1 * np.sqrt(0.2) * np.random.default_rng(4).standard_normal(400))

    def tail(t: float) -> float:  # clean, a reflected ramp to 30 m, a walk-back overshooting to -5.8 m, its turn, clean
        fault = float(np.interp(t, [20.0, 25.0, 30.0, 38.0], [0.0, 30.0, 30.0, -5.0]))
        if 38.0 <= t < 46.0:
            fault = -5.8 + 0.8 * ((t - 42.0) / 4.0) ** 2 * (1.0 if t < 42.0 else 7.25)
        return wander[int(round(t / 0.2))] + (fault if t < 46.0 else 0.0)

    host = {"velocity": np.array([2.0, 0.0]), "velocity_cov": np.diag([0.45**2, 0.1**2]), "until": 75.0, "sigma": 1.5}
    model = _feed(monitors.create("consistency", walk_noise_learned=False), _along_a_wall(until=76.0), tail, doppler=True, **host)
    assert any(v.trusted for t, v in model if 30.0 <= t < 46.0 and abs(tail(t) - wander[int(round(t / 0.2))]) > 2.0)
    learned = _feed(monitors.create("consistency"), _along_a_wall(until=76.0), tail, doppler=True, **host)
    assert not any(v.trusted for t, v in learned if 30.0 <= t < 46.0 and abs(tail(t) - wander[int(round(t / 0.2))]) > 2.0)
    assert all(v.trusted for t, v in learned if t >= 46.0 + 5.0)


def test_the_pf_gives_its_monitor_the_receivers_error_correlation_not_its_likelihoods():
    """The demo, seed 4, pf with combined_cn0 at 1774.9 s: the pf weighs fixes as independent Student-t draws and handed
    that (gps_correlation_s 0) to its monitor, whose window test then took two fixes 2 s apart as independent: its gate
    3.9 times wider than the ekf's, it passed the receiver's walk-back of 1.6 m/s 27.7 m off, and the pf followed it
    (APE p95 31.96 m). The correlation is the receiver's, so both filters give the monitor the same; the pf's likelihood
    keeps its independent draws unless bias_state."""
    pf, ekf = fusion.create("pf"), fusion.create("ekf")
    assert pf.params.gps_correlation_s == ekf.params.gps_correlation_s > 0.0
    assert not pf.params.bias_state
    # the receiver's error there: a reflected ramp to 45 m, its plateau, a walk-back at 1.6 m/s, then back in 5 s
    walk_back = lambda t: float(np.interp(t, [10.0, 14.0, 20.0, 36.0, 41.0], [0.0, 45.0, 45.0, 19.4, 0.0]))
    host = {"velocity": np.array([2.0, 0.0]), "velocity_cov": np.diag([0.45**2, 0.1**2]), "until": 55.0}
    hdop_1 = {"sigma": 3.0 / math.sqrt(2.0), **host}  # uere 3 m at HDOP 1, as both filters weigh a fix
    independent = _feed(monitors.create("consistency"), _along_a_wall(until=56.0), walk_back, correlation_s=0.0, **hdop_1)
    assert any(v.trusted for t, v in independent if 20.0 < t < 36.0)
    receivers = _feed(monitors.create("consistency"), _along_a_wall(until=56.0), walk_back, correlation_s=pf.params.gps_correlation_s, **hdop_1)
    assert not any(v.trusted for t, v in receivers if walk_back(t) > 5.0)
    assert all(v.trusted for t, v in receivers if t >= 45.0)


def test_a_constant_velocity_run_along_an_unobserved_direction_is_trusted():
    """The bound does not refuse good fixes where the extrapolation holds."""
    verdicts = _feed(monitors.create("consistency"), _along_a_wall(), lambda t: 0.0)
    assert all(v.trusted for t, v in verdicts if t >= 5.0)


def test_an_unobserved_direction_moves_with_the_filters_velocity_not_the_matchers_prior():
    """rough_water: in the canal's first 200 m gicp constrains height alone and its prior, never having seen the motion,
    says 0.04 m/s while the boat makes 2 m/s; taking that prior as the displacement refused 77% of fixes good to 0.5 m.
    The host filter's velocity carries the unobserved direction: good fixes are trusted, and a ramp is still refused."""
    stuck = _along_a_wall(prior_mps=0.0)
    east = np.array([2.0, 0.0])
    assert not all(v.trusted for t, v in _feed(monitors.create("consistency"), stuck, lambda t: 0.0) if t >= 5.0)
    assert all(v.trusted for t, v in _feed(monitors.create("consistency"), stuck, lambda t: 0.0, velocity=east) if t >= 5.0)
    ramp = lambda t: 0.0 if t < 20.0 else min(3.0 * (t - 20.0), 40.0)
    verdicts = _feed(monitors.create("consistency"), stuck, ramp, suspect_of=lambda t: 12.0 <= t < 20.0, velocity=east)
    assert not any(v.trusted for t, v in verdicts if ramp(t) > 3.0)


def test_a_filter_velocity_the_filter_itself_doubts_does_not_refuse_good_fixes():
    """quickstart seed 4 at 2006.5 s: one wrong match (5.6 m/s for the true 2.3) gave the ekf 3.7 m/s, +-0.5 and growing;
    the slower matches after it counted as slips, and with the unobserved direction bounded by the monitor's fixed 0.3 m/s
    every good fix was refused as too slow for 43 s (the ekf 84 m off). The window test now takes at least the host's own
    velocity variance along that direction: the good fixes pass it once the re-acquisition guard is over. The price, held
    here: while the host doubts its speed, a ramp's first metres pass the window test too (an 8 m/s walk-back: its fixes
    6.4 and 8.0 m off), and a host never corrected (here no trusted fix updates it, as it would the ekf) drags the
    reference along; the ramp's climb is refused. The stream's start stands for the re-acquisition (startup_guard), with
    the fixed 5 s wait the trace ran with (guard_s = 5): the ramp then meets the drifting reference where it did."""
    track = _along_a_wall()
    waited = {"startup_guard": True, "guard_s": 5.0}
    wrong = np.array([3.7, 0.0])  # the vessel makes 2 m/s east
    assert not any(v.trusted for t, v in _feed(monitors.create("consistency", **waited), track, lambda t: 0.0, velocity=wrong) if t >= 5.0)
    doubted = np.diag([0.9**2, 0.3**2])
    verdicts = _feed(monitors.create("consistency", **waited), track, lambda t: 0.0, velocity=wrong, velocity_cov=doubted)
    assert all(v.trusted for t, v in verdicts if 5.2 <= t < 7.0)  # after the guard (5 s), before the reference drifts
    ramp = lambda t: 0.0 if t < 20.0 else min(8.0 * (t - 20.0), 40.0)
    verdicts = _feed(monitors.create("consistency", **waited), track, ramp, velocity=wrong, velocity_cov=doubted)
    assert not any(v.trusted for t, v in verdicts if 21.1 <= t < 25.0)


def test_a_reference_starts_from_fixes_refused_only_on_their_own_evidence():
    """gps_jump: every fix of open water carried a weak satellite, so no fix was ever trusted and the consistency monitor
    had no reference; the first trusted fix was the jump's. A fix refused on its own evidence now starts the reference,
    and the jump against it is refused."""
    jump = lambda t: 15.0 if 20.0 <= t < 30.0 else 0.0
    verdicts = _feed(monitors.create("consistency"), _along_a_wall(unobserved=1e-4), jump, suspect_of=lambda t: t < 20.0)
    assert not any(v.trusted for t, v in verdicts if 20.0 <= t < 30.0)


def test_a_combined_verdict_is_on_its_own_evidence_only_when_every_refusal_is():
    from fusion.monitors.combined import CombinedMonitor, CombinedParams

    class Fixed(monitors.Monitor):
        def __init__(self, verdict):
            self.verdict = verdict

        def check(self, obs, ctx):
            return self.verdict

    suspect = fusion.Verdict(False, 9.0, "weak", on_its_own=True, rule="cn0.deficit")
    disagrees = fusion.Verdict(False, 50.0, "jump", rule="consistency.window", steady=False)
    both = CombinedMonitor(CombinedParams(), [Fixed(suspect), Fixed(disagrees)]).check(_obs(0.0, [0, 0]), None)
    assert not both.trusted and not both.on_its_own and not both.steady
    assert both.rule == "cn0.deficit+consistency.window"  # every refusing member's rule, in member order
    alone = CombinedMonitor(CombinedParams(), [Fixed(suspect), Fixed(fusion.Verdict(True, 0.1, "ok"))]).check(_obs(0.0, [0, 0]), None)
    assert not alone.trusted and alone.on_its_own and alone.steady and alone.rule == "cn0.deficit"
    unnamed = Fixed(fusion.Verdict(False, 1.0, "a plugin's"))
    unnamed.name = "plugin"
    assert CombinedMonitor(CombinedParams(), [unnamed]).check(_obs(0.0, [0, 0]), None).rule == "plugin"  # no rule: the member's name


def _sky_fix(t: float, sats: list[tuple[float, float, bool]]) -> FixObservation:
    """A fix at t using satellites (azimuth, elevation, used), as GSV/GSA report them."""
    reports = tuple(SatelliteReport(k + 1, az, el, 40.0, used) for k, (az, el, used) in enumerate(sats))
    return FixObservation(t, np.zeros(2), np.eye(2), 0.0, 4.0, 1, 1.0, reports)


def test_shadow_refuses_a_fix_that_uses_a_satellite_behind_a_wall_the_lidar_sees_and_holds_it():
    """A 10 m wall 20 m east of the antenna (its top 21 deg up from the 1.3 m antenna): a used satellite east at 15 deg is
    behind it, one east at 35 deg or west at 15 deg is not, nor is an unused one behind it. The receiver's filter
    carries the blocked one's error on, so the next fixes stay refused for hold_s."""
    mon = monitors.create("shadow", hold_s=2.0)
    y, z = np.meshgrid(np.arange(-30.0, 30.0, 0.25), np.arange(-1.0, 10.0, 0.25))
    mon.add_scan(0.0, np.eye(4), np.column_stack([np.full(y.size, 20.0), y.ravel(), z.ravel()]))
    ctx = FixContext(None, 0.0, 0.0, np.zeros(2), OdometryTrack(), antenna=np.array([0.0, 0.0, 1.3]))

    def verdict(t: float, sats: list[tuple[float, float, bool]]):
        fix = _sky_fix(t, sats)
        v = mon.check(fix, ctx)
        mon.commit(fix, v)
        return v

    assert verdict(0.2, [(90.0, 35.0, True), (270.0, 15.0, True), (90.0, 15.0, False)]).trusted
    blocked = verdict(0.4, [(90.0, 15.0, True), (270.0, 15.0, True)])
    assert not blocked.trusted and blocked.on_its_own and blocked.statistic == 1.0 and blocked.rule == "shadow.blocked"
    held = verdict(1.4, [(270.0, 15.0, True)])
    assert not held.trusted and "ago" in held.reason and held.rule == "shadow.hold"
    assert verdict(2.6, [(270.0, 15.0, True)]).trusted
    mon.reset()  # a re-lock: the map was placed with a pose that was astray
    assert verdict(3.0, [(90.0, 15.0, True)]).trusted


def test_combined_shadow_is_registered_and_maps_the_scans():
    """consistency + shadow by one name: its monitor maps the scans, so the feed gives an ekf with it each scan's points."""
    mon = monitors.create("combined_shadow")
    assert [m.name for m in mon.members] == ["consistency", "shadow"] and mon.wants_scans
    assert fusion.create("ekf", monitor="combined_shadow").wants_scans
    assert not fusion.create("ekf").wants_scans  # the default, combined_cn0


def test_after_an_outage_the_guard_waits_for_the_receivers_own_track_to_move_with_the_odometry():
    """dam_lock_inertial seed 2 at 2379-2383 s: after a 4 s outage at the lock the receiver's first fixes came back 7.5 m
    off and walked back over 2 s. The reference, carried over the outage along a direction the matches left unobserved,
    was as uncertain as that and passed them, and five passes ended the guard: the ekf took fixes 5-7.5 m off. The
    guard's evidence is now the receiver's own track over a window, from half a window after the gap on; a walk-back
    moves against the odometry and fails it. Here the host doubts its speed along the unobserved direction (1.5 m/s), so
    the reference carried over the 4 s outage passes a fix 7 m off; the fixes come back 7 m ahead and walk back at
    3.5 m/s: none of them is trusted, and the fixes on the truth after it are, within 2.5 s (a fixed 5 s wait: 5 s)."""
    track = _along_a_wall(until=41.0)
    ctx = FixContext(
        predicted=None, yaw=0.0, yaw_var=1e-6, lever=np.zeros(2), odometry=track, correlation_s=30.0,
        velocity=np.array([2.0, 0.0]), velocity_cov=np.diag([1.5**2, 0.1**2]),
    )  # fmt: skip
    walk_back = lambda t: max(0.0, 7.0 - 3.5 * (t - 24.0))  # 7 m at the first fix after the outage, 0 from 26 s
    mon, verdicts = monitors.create("consistency"), []
    for t in [*np.arange(0.0, 20.0, 0.2), *np.arange(24.0, 34.0, 0.2)]:
        obs = _obs(float(t), [2.0 * t + (walk_back(t) if t >= 24.0 else 0.0), 0.0], sigma=0.5)
        verdicts.append((round(float(t), 1), walk_back(t) if t >= 24.0 else 0.0, v := mon.check(obs, ctx)))
        mon.commit(obs, v)
    assert not any(v.trusted for t, off, v in verdicts if t >= 24.0 and off > 0.5)
    assert all(v.trusted for t, off, v in verdicts if t >= 28.5)
