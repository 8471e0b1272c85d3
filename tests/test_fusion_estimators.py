"""gps_only, hdop_switch and pf on synthetic streams with exact truth; the antenna lever arm."""

from __future__ import annotations

import math

import numpy as np
from fusion_streams import Fault, StreamSpec, errors, generate, pose_at, run

import fusion


def _initial(t_grid, poses, t=0.0):
    p = pose_at(t_grid, poses, t)
    return (float(p[0]), float(p[1]), math.degrees(p[2]))


def test_gps_only_reports_the_receiver_output_minus_the_antenna():
    events, t_grid, poses = generate(StreamSpec(duration=20.0, lever=(0.0, 0.0), seed=1))
    est = fusion.create("gps_only")
    for kind, stamp, payload in events:
        if kind == "fix":
            est.add_fix(payload)
            assert np.allclose(est.pose[:2, 3], payload.enu[:2])
            assert math.isclose(est.pose[2, 3], payload.enu[2] - 1.3)
        else:
            est.add_match(stamp, payload)
    assert not est.events[1:]  # only the first scan's "no reference" was recorded


def test_gps_only_holds_its_last_output_through_a_blackout():
    spec = StreamSpec(duration=30.0, faults=[Fault(10.0, 20.0, (0, 0), blackout=True)], seed=1)
    events, _, _ = generate(spec)
    est = fusion.create("gps_only")
    held = None
    for kind, stamp, payload in events:
        if kind == "fix":
            v = est.add_fix(payload)
            if 10.0 <= stamp < 20.0:
                assert not v.trusted and "quality 0" in v.reason
                held = est.pose.copy() if held is None else held
                assert np.array_equal(est.pose, held)


def test_hdop_switch_dead_reckons_through_a_blackout_with_the_odometry():
    spec = StreamSpec(duration=40.0, odom_sigma=(0.0, 0.0, 0.0), faults=[Fault(20.0, 35.0, (0, 0), blackout=True)], uere=0.01, seed=5)
    events, t_grid, poses = generate(spec)
    est = fusion.create("hdop_switch", uere_m=0.01)
    out = run(est, events)
    err = errors(out, t_grid, poses)
    blackout = (out["stamp"] > 20.0) & (out["stamp"] < 35.0)
    assert np.abs(err[blackout, :2]).max() < 0.2  # perfect odometry from the last trusted fix
    assert np.degrees(np.abs(err[blackout, 2]).max()) < 0.5


def test_pf_follows_gps_and_odometry_and_shrugs_off_a_wild_fix():
    # white GPS noise, and filters told so: then the Gaussian ekf takes a full-weight hit
    spec = StreamSpec(duration=60.0, faults=[Fault(40.0, 40.2, (40.0, -30.0))], gps_tau=0.0, seed=6)
    events, t_grid, poses = generate(spec)
    pf = fusion.create("pf", gps_correlation_s=0.0, initial_pose=_initial(t_grid, poses))
    ekf = fusion.create("ekf", monitor="none", gps_correlation_s=0.0, initial_pose=_initial(t_grid, poses))
    err = {name: errors(run(est, events), t_grid, poses) for name, est in (("pf", pf), ("ekf", ekf))}
    stamps = np.array([e[1] for e in events])
    steady = (stamps > 10.0) & (stamps < 40.0)
    assert np.sqrt(np.mean(np.sum(err["pf"][steady, :2] ** 2, axis=1))) < 1.5
    wild = int(np.flatnonzero(stamps >= 40.0)[0]) + 1  # the event after the 50 m wrong fix
    jump = {name: float(np.hypot(*(e[wild, :2] - e[wild - 2, :2]))) for name, e in err.items()}
    assert jump["pf"] < 0.5
    assert jump["ekf"] > 2.0  # without a gate the Gaussian update is dragged


def test_pf_is_deterministic_for_a_seed():
    events, _, _ = generate(StreamSpec(duration=15.0, seed=8))
    a = run(fusion.create("pf", seed=3), events)["est"]
    b = run(fusion.create("pf", seed=3), events)["est"]
    c = run(fusion.create("pf", seed=4), events)["est"]
    assert np.array_equal(a, b, equal_nan=True)
    assert not np.array_equal(a, c, equal_nan=True)


def test_pf_leans_on_gps_along_a_degenerate_axis():
    degenerate = np.diag([25.0, 0.01**2, math.radians(0.05) ** 2])
    spec = StreamSpec(duration=60.0, turn_amp_dps=0.0, odom_sigma=(0, 0, 0), odom_cov_scale=degenerate, odom_corrupt=(0.0, 1.0), seed=3)
    events, t_grid, poses = generate(spec)
    out = run(fusion.create("pf", initial_pose=_initial(t_grid, poses), odom_slip_frac=0.0, odom_slip_sigmas=0.0), events)  # no slip here
    err = errors(out, t_grid, poses)
    late = out["stamp"] > 20.0
    gps = np.array([f.truth.error[:2] for k, t, f in events if k == "fix" and t > 20.0])
    gps_rms = np.sqrt(np.mean(np.sum(gps**2, axis=1)))
    assert np.sqrt(np.mean(np.sum(err[late, :2] ** 2, axis=1))) < 1.5 * gps_rms + 0.5


def test_antenna_lever_arm_is_taken_into_account():
    lever = (-1.5, 0.8)
    events, t_grid, poses = generate(StreamSpec(duration=60.0, lever=lever, gps_tau=0.0, seed=9))
    with_lever = fusion.create("ekf", monitor="none", antenna=(lever[0], lever[1], 1.3), gps_correlation_s=0.0)
    without = fusion.create("ekf", monitor="none", gps_correlation_s=0.0)
    late = None
    rms = {}
    for name, est in (("with", with_lever), ("without", without)):
        out = run(est, events)
        err = errors(out, t_grid, poses)
        late = np.isfinite(err[:, 0]) & (out["stamp"] > 20.0)
        rms[name] = np.sqrt(np.mean(np.sum(err[late, :2] ** 2, axis=1)))
    assert rms["with"] < 0.8
    assert rms["without"] > rms["with"] + 0.5


def test_ekf_relocks_onto_gps_after_refusing_every_fix():
    # A wrong, confident start: the NIS gate refuses every fix until the filter re-locks onto GPS.
    events, t_grid, poses = generate(StreamSpec(duration=60.0, seed=10))
    x, y, yaw = _initial(t_grid, poses)
    ekf = fusion.create("ekf", monitor="nis", initial_pose=(x + 80.0, y - 60.0, yaw), initial_sigma=(0.5, 1.0))
    out = run(ekf, events)
    err = errors(out, t_grid, poses)
    relocks = [e for e in ekf.events if "re-locked" in e.reason]
    assert len(relocks) == 1 and 30.0 <= relocks[0].stamp < 32.0
    assert np.hypot(*err[out["stamp"] < 29.0, :2].T).min() > 90.0
    assert np.hypot(*err[out["stamp"] > 40.0, :2].T).max() < 8.0
