"""Start-up alignment (fusion.bootstrap): the heading it starts a filter on is as good as the uncertainty it claims; a
vessel that starts at rest has its position first and its heading from its course, its travel or a compass.

A boat under way along +x (true yaw 0) in open water, the bench's receiver model with its time-correlated errors,
and either exact odometry (the odometry track's fit) or none (the GPS course). The first accepted alignment of
each start must lie within two of its own claimed heading sigmas: a filter started on a heading it trusts more than
it should never recovers it without GPS (docs/models.md, the start-up paragraph).
"""

from __future__ import annotations

from datetime import timedelta

import fusion_streams as fs
import gnss_worlds as gw
import numpy as np
import pytest

import fusion
from fusion.bootstrap import HEADING_FROM_COMPASS, HEADING_FROM_COURSE, HEADING_FROM_MOTION, Alignment, Bootstrap
from fusion.ekf import EkfParams
from fusion.observation import screen
from fusion.odometry import OdometryTrack
from riverbench.samples import HeadingSample
from sim import GnssReceiver

STARTS = 12
"""Starts per case, spread over the ephemeris file's span (satellite geometry and the receiver's slow errors vary)."""


def first_alignments(with_odometry: bool, on_course: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Yaw error (deg) and claimed yaw sigma (deg) of each start's first accepted alignment: the travel's (Bootstrap.alignment)
    or, `on_course`, the receiver's course over ground (Bootstrap.under_way)."""
    p = EkfParams()
    world, boat = gw.open_water(), gw.Straight(speed=2.0)
    sky = GnssReceiver().constellation
    errors, sigmas = [], []
    for k in range(STARTS):
        epoch = sky.start_utc + (sky.end_utc - sky.start_utc - timedelta(seconds=300)) * (k / STARTS)
        receiver = GnssReceiver(seed=k, epoch_utc=epoch)
        bootstrap = Bootstrap(p.init_baseline_m, p.init_min_fixes, p.init_max_hdop, np.zeros(2), p.init_max_yaw_sd_deg)
        odometry, next_scan = OdometryTrack(), 0.0
        for t in receiver.epochs(200.0):
            while with_odometry and next_scan <= t:  # exact 10 Hz steps of a boat at 2 m/s
                odometry.add(next_scan, np.array([0.2, 0.0, 0.0]), np.diag([1e-6, 1e-6, 1e-8]))
                next_scan = round(next_scan + 0.1, 9)
            obs, _ = screen(receiver.fix(world, boat, t), p.uere_m, False)
            if obs is None or t < 20.0:  # a boat already under way: the receiver's own filter has settled
                continue
            bootstrap.add(obs, odometry)
            if on_course:
                alignment = bootstrap.under_way(obs.stamp, p.init_course_speed_mps, np.radians(p.course_heading_sigma_deg) ** 2)
            else:
                alignment = bootstrap.alignment(obs.stamp)
            if alignment is not None:
                errors.append((np.degrees(alignment.pose[2]) + 180.0) % 360.0 - 180.0)
                sigmas.append(np.degrees(np.sqrt(alignment.cov[2, 2])))
                break
    return np.array(errors), np.array(sigmas)


@pytest.mark.parametrize("with_odometry", [True, False], ids=["odometry-fit", "gps-course"])
def test_the_start_heading_lies_within_two_of_its_claimed_sigmas_in_open_water(with_odometry):
    errors, sigmas = first_alignments(with_odometry)
    assert len(errors) == STARTS  # every start aligned within the 200 s
    assert np.all(sigmas <= EkfParams().init_max_yaw_sd_deg + 1e-9)
    z = errors / sigmas
    assert np.all(np.abs(z) <= 2.0), f"yaw errors {errors.round(2)} deg against claimed sigmas {sigmas.round(2)} deg"
    assert np.sqrt(np.mean(z**2)) <= 1.0


def test_a_vessel_under_way_starts_on_its_course_over_ground_within_its_fixes():
    """The receiver's Doppler course starts a filter after init_min_fixes fixes (1 s at 5 Hz), not after a travel; in
    open water with no leeway it is off by the velocity's own error (0.05 m/s at 2 m/s over 5 fixes: about 0.7 deg), well
    within the leeway's 10 deg the heading claims."""
    errors, sigmas = first_alignments(with_odometry=False, on_course=True)
    assert len(errors) == STARTS
    assert np.allclose(sigmas, EkfParams().course_heading_sigma_deg)
    assert np.all(np.abs(errors) <= 3.0), f"yaw errors {errors.round(2)} deg"
    assert np.sqrt(np.mean(errors**2)) <= 1.5


def test_the_ekf_starts_under_way_within_its_first_fixes_or_after_its_travel():
    """init_on_course: the ekf on a boat under way has a pose after init_min_fixes fixes (HEADING_FROM_COURSE); without it
    it waits for init_baseline_m of track (the travel alignment)."""
    world, boat = gw.open_water(), gw.Straight(speed=2.0)
    started = {}
    for on_course in (True, False):
        est = fusion.create("ekf", init_on_course=on_course)
        receiver = GnssReceiver(seed=3)
        first = None
        for t in receiver.epochs(60.0):
            fix = receiver.fix(world, boat, t)
            first = t if first is None and fix.quality in (1, 2) else first
            est.add_fix(fix)
            if est.initialized:
                yaw = float(np.degrees(np.arctan2(est.pose[1, 0], est.pose[0, 0])))
                started[on_course] = (t - first, est.heading_from, yaw)
                break
    assert abs(started[True][2]) <= 5.0
    assert started[True][1] == HEADING_FROM_COURSE
    assert started[True][0] <= 1.0 + 1e-9  # init_min_fixes = 5 fixes at 5 Hz
    assert started[False][1] == HEADING_FROM_MOTION
    assert started[False][0] >= EkfParams().init_baseline_m / 2.0 / 2.0  # at 2 m/s, at least half the baseline's travel


class MooredThenUnderWay:
    """A vessel at rest at the origin with heading yaw_deg until t_leave, then ahead along that heading at `speed`."""

    def __init__(self, yaw_deg: float, t_leave: float, speed: float = 2.0) -> None:
        self.yaw, self.t_leave, self.speed = np.radians(yaw_deg), t_leave, speed

    def pose(self, t: float) -> np.ndarray:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        run = self.speed * max(t - self.t_leave, 0.0)
        return np.array([[c, -s, 0.0, c * run], [s, c, 0.0, s * run], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def start_from_rest(name: str, seed: int, compass_at: float | None = None) -> tuple[object, list[tuple[float, np.ndarray, int]]]:
    """An estimator fed the bench's receiver on a vessel moored for 60 s (yaw 60 deg) that then leaves; with compass_at, one
    undisturbed compass heading (the true one) at that time. Returns the estimator and its (t, pose, the fix's quality) after each fix."""
    boat = MooredThenUnderWay(60.0, 60.0)
    receiver = GnssReceiver(seed=seed)
    estimator = fusion.create(name, antenna=(0.5, 0.0, 1.5))
    poses = []
    for t in receiver.epochs(120.0):
        if compass_at is not None and compass_at <= t < compass_at + 0.2:
            estimator.add_heading(HeadingSample(t, float(boat.yaw), np.array([19.9, -5.0, -47.0]), np.radians(1.0), 66.35))
        fix = receiver.fix(gw.open_water(), boat, t)
        estimator.add_fix(fix)
        poses.append((t, estimator.pose, fix.quality))
    return estimator, poses


@pytest.mark.parametrize("name", ["ekf", "pf", "hdop_switch"])
@pytest.mark.parametrize("seed", [0, 7])
def test_a_moored_vessel_has_its_position_first_and_its_heading_once_it_moves(name, seed):
    """At rest the receiver reports no speed: the estimator starts on its position within the first fixes, heading unknown;
    once under way the course over ground (or the travel) gives the heading, and it is the true one."""
    estimator, poses = start_from_rest(name, seed)
    p = estimator.params
    # init_min_fixes fixes below init_static_speed_mps: the receiver's speed at rest scatters up to 0.8 m/s while its filter settles
    first_fix = next(t for t, _, quality in poses if quality)
    assert estimator.position_at - first_fix <= 3.0
    at_rest = [pose for t, pose, _ in poses if estimator.position_at <= t < 60.0]
    assert all(np.isfinite(pose).all() and np.hypot(*pose[:2, 3]) < 5.0 for pose in at_rest)
    assert estimator.heading_from in (HEADING_FROM_COURSE, HEADING_FROM_MOTION)
    assert 60.0 < estimator.heading_at < 70.0
    # the heading it starts on lies within two of its stated sigmas (a course's: course_heading_sigma_deg) of the truth
    [pose] = [pose for t, pose, _ in poses if t == estimator.heading_at]
    assert abs(np.degrees(np.arctan2(pose[1, 0], pose[0, 0])) - 60.0) < 2.0 * p.course_heading_sigma_deg


@pytest.mark.parametrize("name", ["ekf", "pf"])
def test_a_compass_gives_a_moored_vessel_its_heading(name):
    estimator, poses = start_from_rest(name, 3, compass_at=10.0)
    assert estimator.heading_from == HEADING_FROM_COMPASS and 10.0 <= estimator.heading_at < 10.2
    [pose] = [pose for t, pose, _ in poses if 10.0 <= t < 10.2]  # at rest, the compass's heading the filter's
    assert abs(np.degrees(np.arctan2(pose[1, 0], pose[0, 0])) - 60.0) < 3.0


@pytest.mark.parametrize("seed", range(6))
def test_a_filter_started_on_a_degenerate_match_takes_its_speed_from_the_receiver(seed):
    """Along a featureless canal the matcher observes the sideways motion but not the forward one: its step forward is a
    prior that never saw the motion (0.02 of the truth) with a variance of 1e4 m^2. The ekf starts its velocity there from
    the receiver's velocity over ground (RMC/VTG), not from that prior, so its consistency monitor trusts the good fixes
    that follow and the estimate stays with them (rough_water at start-up: without it the monitor refused 48-70% of the
    fixes and the ekf ran 42-45 m off on seeds 1-3 of this stream)."""
    spec = fs.StreamSpec(uere=1.0, odom_corrupt=(0.02, 1.0), odom_cov_scale=np.diag([1e4, 9e-4, 1e-5]), report_velocity=True, seed=seed)
    events, t_grid, poses = fs.generate(spec)
    estimator = fusion.create("ekf", matcher="m")
    out = fs.run(estimator, events)
    started = out["stamp"] >= estimator.position_at
    error = np.hypot(*fs.errors(out, t_grid, poses)[started, :2].T)
    refused = [not verdict.trusted for stamp, verdict, _ in out["verdicts"] if stamp >= estimator.position_at]
    assert np.mean(refused) <= 0.05
    assert error.max() < 5.0


def test_the_start_velocity_takes_the_receivers_where_the_odometry_did_not_observe():
    """Information-form fusion, by hand: forward unobserved by the odometry (1e6 m^2/s^2) -> the receiver's 2 m/s;
    sideways observed to 0.01 m/s -> the odometry's 0.1 m/s, the receiver's 0.5 m/s moving it by a few hundredths of a
    percent: turned into the body by a heading known to 2 deg, the receiver's sideways velocity is uncertain by its
    0.5 m/s sigma and by its speed (2.06 m/s) times 2 deg, in quadrature."""
    heading = np.radians(30.0)
    ground = 2.0 * np.array([np.cos(heading), np.sin(heading)]) + 0.5 * np.array([-np.sin(heading), np.cos(heading)])
    alignment = Alignment(10.0, np.array([0.0, 0.0, heading]), np.diag([1.0, 1.0, np.radians(2.0) ** 2]), ground_velocity=ground)
    odometry = (np.array([0.04, 0.1, 0.0]), np.diag([1e6, 1e-4, 1e-6]))
    mean, cov = alignment.start_velocity(odometry, 0.5)
    assert mean[0] == pytest.approx(2.0, abs=1e-6) and cov[0, 0] == pytest.approx(0.25, rel=1e-6)
    across = 0.25 + (2.0**2 + 0.5**2) * np.radians(2.0) ** 2
    assert mean[1] == pytest.approx(0.1 + (0.5 - 0.1) * 1e-4 / (1e-4 + across), abs=1e-9)
    assert Alignment(10.0, np.zeros(3), np.eye(3)).start_velocity(odometry, 0.5)[0] == pytest.approx([0.04, 0.1])
