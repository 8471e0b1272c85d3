"""The LiDAR obstacle map (fusion.obstacles): a wall of known height blocks exactly the satellites whose line of sight
passes below its top, seen from where the vessel is now, with what it saw of the wall from elsewhere kept."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion.obstacles import ObstacleMap, ObstacleMapParams


def wall_points(x_m: float, height_m: float, y_span: tuple[float, float] = (-60.0, 60.0)) -> np.ndarray:
    """A vertical wall facing the vessel at base_link x = x_m, sampled every 0.25 m from the water (z = -1) to its top."""
    y, z = np.meshgrid(np.arange(*y_span, 0.25), np.arange(-1.0, height_m + 1e-9, 0.25))
    return np.column_stack([np.full(y.size, x_m + 0.1), y.ravel(), z.ravel()])


def pose_at(x: float, y: float, yaw_deg: float = 0.0) -> np.ndarray:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


@settings(max_examples=60, deadline=None)
@given(
    distance=st.floats(8.0, 80.0),
    height=st.floats(2.0, 25.0),
    yaw=st.floats(-180.0, 180.0),
    el=st.floats(1.0, 80.0),
)
def test_a_wall_blocks_the_satellites_below_its_top_and_no_others(distance, height, yaw, el):
    """Wall at `distance` ahead of a vessel heading `yaw` (deg from east, counter-clockwise), top at `height` (base_link z);
    the antenna at 1.3 m. A satellite straight over the wall is blocked iff its elevation is below the top's as seen from the
    antenna (less the map's margin and cell); one on the opposite bearing never is."""
    p = ObstacleMapParams()
    omap = ObstacleMap(p)
    omap.add(0.0, pose_at(0.0, 0.0, yaw), wall_points(distance, height))
    antenna = np.array([0.0, 0.0, 1.3])
    bearing = (90.0 - yaw) % 360.0  # the wall's azimuth, clockwise from north
    top = math.degrees(math.atan2(height - 1.3 - p.margin_m, distance))
    slack = math.degrees(math.atan2(2.0 * p.cell_m, distance)) + 0.5  # the wall's face spans a cell or two
    ahead, behind = omap.blocked(0.0, antenna, np.array([bearing, bearing + 180.0]), np.array([el, el]))
    assert not behind
    if el < top - slack:
        assert ahead
    if el > top + slack:
        assert not ahead


def test_a_wall_seen_from_afar_stays_known_alongside_and_is_forgotten_after_the_horizon():
    """From 80 m away the top beam (10.67 deg) sees a 12 m wall whole; alongside at 15 m it sees only its foot (up to
    2.8 m), yet the satellite 30 deg up over the wall (top at 35 deg from there) is blocked; after horizon_s it is not."""
    p = ObstacleMapParams(horizon_s=60.0)
    omap = ObstacleMap(p)
    omap.add(0.0, pose_at(0.0, 0.0), wall_points(80.0, 12.0))
    alongside = wall_points(15.0, 15.0 * math.tan(math.radians(10.67)))
    omap.add(30.0, pose_at(65.0, 0.0), alongside)
    antenna = np.array([65.0, 0.0, 1.3])
    assert omap.blocked(30.0, antenna, np.array([90.0]), np.array([30.0]))[0]
    assert not omap.blocked(95.0, antenna, np.array([90.0]), np.array([30.0]))[0]


def test_the_map_scrolls_with_the_vessel_and_keeps_what_it_saw():
    """A 300 m run east in 10 m steps (the map is 400 m): the wall first seen at x = 100 m stays where it was."""
    p = ObstacleMapParams()
    omap = ObstacleMap(p)
    for k, x in enumerate(np.arange(0.0, 301.0, 10.0)):
        points = wall_points(100.0 - x, 10.0, (-5.0, 5.0)) if x <= 90.0 else np.zeros((0, 3))
        omap.add(float(k), pose_at(x, 0.0), points)
    # from x = 120 (20 m past the wall) looking back west over it
    assert omap.blocked(30.0, np.array([120.0, 0.0, 1.3]), np.array([270.0]), np.array([15.0]))[0]
    assert not omap.blocked(30.0, np.array([120.0, 0.0, 1.3]), np.array([90.0]), np.array([15.0]))[0]


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_inputs_block_nothing_and_never_raise(bad):
    p = ObstacleMapParams()
    omap = ObstacleMap(p)
    omap.add(0.0, pose_at(0.0, 0.0), np.vstack([wall_points(20.0, 10.0), [bad, 1.0, 2.0]]))
    assert not omap.blocked(0.0, np.array([bad, 0.0, 1.3]), np.array([90.0]), np.array([10.0]))[0]
    assert not omap.blocked(0.0, np.array([0.0, 0.0, 1.3]), np.array([bad]), np.array([10.0]))[0]
    omap.add(1.0, np.full((4, 4), bad), wall_points(20.0, 10.0))
