"""scenarios.pipeline.stream: lazy time-ordered scans and fixes from the simulator, and the tests' drive helper."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from stream_drive import drive

import fusion
import matcher
import sim
import worlds
from scenarios.pipeline.stream import FixEvent, ScanEvent, events
from sim.gnss import GnssReceiver


@pytest.fixture(scope="module")
def setup():
    world = worlds.load("charles_river")
    return world, sim.Trajectory(world)


def test_events_are_lazy_and_time_ordered(setup):
    world, trajectory = setup
    stream = events(world, trajectory, sim.HDL32E(), GnssReceiver(), 10.0, 12.0)
    assert inspect.isgenerator(stream)
    got = list(stream)
    stamps = [e.stamp for e in got]
    assert stamps == sorted(stamps)
    scans = [e for e in got if isinstance(e, ScanEvent)]
    fixes = [e for e in got if isinstance(e, FixEvent)]
    assert len(scans) == 20 and len(fixes) == 10
    assert all(e.scan.stamp == e.stamp and len(e.scan) > 0 for e in scans)
    assert all(e.fix.stamp == e.stamp for e in fixes)


def test_bad_time_range_is_a_clear_error(setup):
    world, trajectory = setup
    with pytest.raises(ValueError, match="t_start < t_end"):
        next(events(world, trajectory, sim.HDL32E(), GnssReceiver(), 5.0, 5.0))
    with pytest.raises(ValueError, match="duration"):
        next(events(world, trajectory, sim.HDL32E(), GnssReceiver(), 0.0, trajectory.duration + 10.0))


def test_drive_collects_estimates_against_truth(setup):
    world, trajectory = setup
    estimators = {"gps_only": fusion.create("gps_only"), "ekf": fusion.create("ekf", matcher="kiss_icp")}
    seen = []
    track = drive(
        world, trajectory, sim.HDL32E(), GnssReceiver(), {"kiss_icp": matcher.create("kiss_icp")}, estimators, 20.0, 26.0, on_event=seen.append
    )
    assert len(track.scan_stamp) == 60 and len(track.fix_stamp) == 30 and len(seen) == 90
    truth = np.array([trajectory.pose(t)[:2, 3] for t in track.scan_stamp])
    assert np.allclose(track.truth[:, :2], truth)
    assert track.match_ok["kiss_icp"][1:].mean() > 0.9  # the first scan has no reference
    gps = track.error("gps_only")
    assert np.all(np.isfinite(gps[track.scan_stamp > 20.3]))
    assert np.nanmax(gps) < 10.0
    assert np.all(np.isfinite(track.fix_error)) and np.all(track.fix_quality == 2)  # measured SBAS fixes (the default receiver)
    assert track.trusted["ekf"].shape == track.statistic["ekf"].shape == (30,)
    assert track.cov["ekf"].shape == (60, 3, 3)


def test_drive_needs_each_estimators_matcher(setup):
    world, trajectory = setup
    with pytest.raises(ValueError, match="estimator 'ekf' uses matcher 'gicp'"):
        drive(
            world,
            trajectory,
            sim.HDL32E(),
            GnssReceiver(),
            {"kiss_icp": matcher.create("kiss_icp")},
            {"ekf": fusion.create("ekf", matcher="gicp")},
            0.0,
            1.0,
        )
