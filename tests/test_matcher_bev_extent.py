"""bev3dof past the Longfellow Bridge (quickstart's full stretch, issue 39 item 4): from about 63 s the bridge recedes
behind the image's half-side (extent_m, 45 m) while the basin's banks are 50-100 m away, inside the matcher's range
band (max_range_m, 100 m) but outside the image. From 81 s the image is empty though the scan has 6,000 returns, and
every match fails; an image that reaches the range band matches them."""

from __future__ import annotations

import numpy as np
import pytest

import matcher
import scenarios
from matcher.motion import pose_to_xyzrpy
from scenarios.pipeline.assembly import assemble


@pytest.fixture(scope="module")
def basin():
    """quickstart (seed 0) 85-86 s into its full stretch: scans and the true relative lidar poses."""
    a = assemble(scenarios.load("quickstart"))
    scans = [a.lidar.scan(a.world, a.trajectory, a.t_start + 85.0 + 0.1 * k) for k in range(11)]
    return a, scans


def _register(a, scans, **params):
    m = matcher.create("bev3dof", **params)
    out = []
    for scan in scans:
        r = m.register(scan)
        if "ref_stamp" in r.info:
            truth = np.linalg.inv(a.trajectory.lidar_pose(r.info["ref_stamp"])) @ a.trajectory.lidar_pose(scan.stamp)
            out.append((r, truth))
    return out


def test_the_default_image_is_empty_in_the_basin(basin):
    a, scans = basin
    for r, _ in _register(a, scans):
        assert not r.ok and r.info["reason"] == "too few points in the image"
        assert r.n_points > 5000  # the returns are there, 45-100 m away


def test_an_image_as_wide_as_the_range_band_matches_there(basin):
    a, scans = basin
    results = _register(a, scans, extent_m=100.0, pixel_m=0.6)  # as many pixels as the default image
    for r, truth in results:
        assert r.ok, r.info.get("reason")
        e = pose_to_xyzrpy(np.linalg.inv(truth) @ r.T)
        assert np.hypot(e[0], e[1]) < 0.1 and abs(np.degrees(e[5])) < 0.2
