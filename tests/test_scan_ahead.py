"""LiDAR revolutions cast ahead in a worker process: the very scans the run's own lidar casts, in order; the worker's
failure reaches the run word for word; stopping early leaves no process behind."""

import math
import multiprocessing as mp

import numpy as np
import pytest

import scenarios
from scenarios.pipeline.assembly import assemble
from scenarios.pipeline.scan_ahead import AHEAD_SCANS, ScanAhead
from scenarios.pipeline.stream import scan_times


def scenario():
    return scenarios.load("rough_water", set=["stretch={start_s = 60.0, end_s = 70.0}"])


def test_the_worker_casts_the_same_revolutions_as_the_run():
    run = assemble(scenario()).vessel_run
    times = scan_times(run.lidar, run.t_start, run.t_end)[:3]
    with ScanAhead(scenario(), times) as ahead:
        for t in times:
            there, here = ahead.scan(float(t)), run.lidar.scan(run.world, run.trajectory, float(t))
            assert there.stamp == here.stamp and there.points.tobytes() == here.points.tobytes()


def test_a_failed_revolution_raises_the_workers_reason_and_asking_out_of_order_is_refused():
    with ScanAhead(scenario(), np.array([60.0, math.nan])) as ahead:
        with pytest.raises(RuntimeError, match=r"expected the revolution at t=61\.0+ s, got scan 60\.0"):
            ahead.scan(61.0)
        with pytest.raises(RuntimeError, match=r"^lidar: scan start time is not finite \(nan\)$"):
            ahead.scan(math.nan)


def test_stopping_before_the_last_revolution_ends_the_worker():
    run = assemble(scenario()).vessel_run
    times = scan_times(run.lidar, run.t_start, run.t_end)
    assert len(times) > 2 * AHEAD_SCANS  # it is still casting (or waiting on a full queue) when closed
    with ScanAhead(scenario(), times) as ahead:
        ahead.scan(float(times[0]))
    assert not mp.active_children()
    assert ahead.rss_mb > 0  # it reported its peak memory on the way out
