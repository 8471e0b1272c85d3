"""gicp against a keyframe (keyframe_m) on charles_river's quays against exact truth: the chained heading drifts less
than scan to scan, each step is still the motion since the previous scan, and keyframes are the default."""

from __future__ import annotations

import math

import numpy as np
import pytest

import matcher
import sim
import worlds
from matcher.motion import pose_to_xyzrpy

STATION_M = 3300.0  # the quickstart stretch's quays: walls and buildings on one side, the basin on the other
SCANS = 150


@pytest.fixture(scope="module")
def chains():
    """Per keyframe_m (0, 1): the chained heading error (deg) at the end, the steps' planar errors (m) and the reference stamps."""
    world = worlds.load("charles_river")
    traj = sim.Trajectory(world, start_m=STATION_M, seed=1)
    lidar = sim.HDL32E(seed=1)
    scans = [lidar.scan(world, traj, 0.1 * k) for k in range(SCANS)]
    out = {}
    for keyframe_m in (0.0, 1.0):
        m = matcher.create("gicp", keyframe_m=keyframe_m)
        chain, steps, refs = np.eye(4), [], []
        for scan in scans:
            r = m.register(scan)
            if not r.ok:
                continue
            chain = chain @ r.T
            truth = np.linalg.inv(traj.lidar_pose(r.info["ref_stamp"])) @ traj.lidar_pose(scan.stamp)
            steps.append(np.hypot(*(np.linalg.inv(truth) @ r.T)[:2, 3]))
            refs.append((r.info["ref_stamp"], scan.stamp))
        truth = np.linalg.inv(traj.lidar_pose(scans[0].stamp)) @ traj.lidar_pose(scans[-1].stamp)
        out[keyframe_m] = (abs(math.degrees(pose_to_xyzrpy(np.linalg.inv(truth) @ chain)[5])), np.array(steps), refs)
    return out


def test_keyframes_are_the_default():
    assert matcher.create("gicp").params.keyframe_m == 1.0


def test_a_keyframe_chain_drifts_less_in_heading(chains):
    scan_to_scan, keyframed = chains[0.0][0], chains[1.0][0]
    assert keyframed < 0.5 * scan_to_scan, f"chained yaw error {keyframed:.3f} deg against {scan_to_scan:.3f} scan to scan"


def test_each_step_is_still_the_motion_since_the_previous_scan(chains):
    steps, refs = chains[1.0][1], chains[1.0][2]
    assert len(steps) == SCANS - 1
    assert all(abs(now - ref - 0.1) < 1e-6 for ref, now in refs)  # the contract: T relative to the previous good scan
    assert np.percentile(steps, 95) < 0.05
