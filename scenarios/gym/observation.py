"""What the agent observes, built from what the vessel's own sensors and estimator give (never the truth)."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from riverbench.angles import wrap_angle
from sim.lidar import HDL32E_ELEVATION_DEG
from worlds.route import Route

RING_ROWS = np.argsort(np.argsort(-HDL32E_ELEVATION_DEG))
"""Row of each laser id in the range image: row 0 the highest beam, row 31 the lowest (as an image is read)."""
MAX_SATS = 32.0


def space(azimuth_bins: int, max_range_m: float) -> spaces.Dict:
    """The observation space (see RiverNavEnv for the meaning of every entry)."""
    big = np.float32(1e6)
    return spaces.Dict(
        {
            "estimate": spaces.Box(-big, big, (3,), np.float32),
            "estimate_cov": spaces.Box(-big, big, (3, 3), np.float32),
            "estimate_valid": spaces.Discrete(2),
            "gps": spaces.Box(np.array([-big, -big, 0.0, 0.0, 0.0], np.float32), np.array([big, big, 99.99, MAX_SATS, big], np.float32)),
            "gps_quality": spaces.Discrete(10),
            "lidar": spaces.Box(0.0, np.float32(max_range_m), (32, azimuth_bins), np.float32),
        }
    )


def route_frame(route: Route, start_station_m: float, xy: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """(along-track from the stretch start, cross-track left +, heading error) and the rotation from ENU x,y to (along, cross)."""
    station, cross, heading = route.project(np.asarray(xy, dtype=float)[:2])
    c, s = math.cos(float(heading)), math.sin(float(heading))
    rot = np.array([[c, s], [-s, c]])
    error = wrap_angle(yaw - float(heading))
    return np.array([float(station) - start_station_m, float(cross), error]), rot


def estimate(route: Route, start_station_m: float, pose: np.ndarray, cov: np.ndarray) -> dict:
    """The estimator's pose and (x, y, yaw) covariance in the route frame; zeros and valid=0 before it has one."""
    pose, cov = np.asarray(pose, dtype=float), np.asarray(cov, dtype=float)
    if not (np.isfinite(pose).all() and cov.shape == (3, 3) and np.isfinite(cov).all()):
        return {"estimate": np.zeros(3, np.float32), "estimate_cov": np.zeros((3, 3), np.float32), "estimate_valid": 0}
    rel, rot = route_frame(route, start_station_m, pose[:2, 3], math.atan2(pose[1, 0], pose[0, 0]))
    full = np.eye(3)
    full[:2, :2] = rot
    return {"estimate": rel.astype(np.float32), "estimate_cov": (full @ cov @ full.T).astype(np.float32), "estimate_valid": 1}


def gps(route: Route, start_station_m: float, fix, now: float) -> dict:
    """The latest fix as the receiver reported it: (along, cross, hdop, satellites used, age s) and its GGA quality."""
    if fix is None:
        return {"gps": np.array([0.0, 0.0, 99.99, 0.0, 0.0], np.float32), "gps_quality": 0}
    has_position = fix.quality != 0 and np.isfinite(np.asarray(fix.enu, dtype=float)).all()
    rel = route_frame(route, start_station_m, np.asarray(fix.enu)[:2], 0.0)[0] if has_position else np.zeros(3)
    hdop = float(fix.hdop) if np.isfinite(fix.hdop) else 99.99
    return {
        "gps": np.array([rel[0], rel[1], min(hdop, 99.99), min(float(fix.num_sats), MAX_SATS), max(now - fix.stamp, 0.0)], np.float32),
        "gps_quality": int(fix.quality),
    }


def range_image(points: np.ndarray, azimuth_bins: int, max_range_m: float) -> np.ndarray:
    """(32, bins) nearest range per beam and azimuth bin from a scan's points (lidar frame); 0 where nothing returned.

    Azimuth bins run counter-clockwise from straight behind (-180 deg) through ahead (0) to +180 deg.
    """
    image = np.full((32, azimuth_bins), np.inf, dtype=np.float32)
    if len(points):
        x, y, z = (points[k].astype(np.float64) for k in ("x", "y", "z"))
        rng = np.sqrt(x * x + y * y + z * z)
        col = np.minimum(((np.arctan2(y, x) + math.pi) / (2.0 * math.pi) * azimuth_bins).astype(int), azimuth_bins - 1)
        np.minimum.at(image, (RING_ROWS[points["ring"].astype(int)], col), np.minimum(rng, max_range_m).astype(np.float32))
    image[~np.isfinite(image)] = 0.0
    return image
