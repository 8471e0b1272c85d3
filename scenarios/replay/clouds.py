"""A sensor_msgs/PointCloud2 read into a Scan, from the fields a LiDAR driver lays out.

- x, y, z (any float type): required; points with a non-finite coordinate (a driver's no-return
  NaN in an organised cloud) are left out.
- intensity | i | reflectivity: kept in the driver's own scale (the velodyne driver's is the
  sensor's 0-255 calibrated reflectivity, as the simulator's); missing -> 0.
- ring: velodyne_pointcloud's ring, the elevation rank (0 the lowest beam; scenarios.export.dialect),
  read back into the HDL-32E laser id the simulator numbers rings by (a ring of 32 or more, not an
  HDL-32E's, is kept). laser_id | channel: the laser id as it is. Missing -> the nearest HDL-32E
  beam by elevation (its laser id) when every point lies within the HDL-32E's vertical field of
  view, else 0.
- time | t | timestamp | timestamps: per-point time; float seconds relative to the header stamp
  (velodyne), integer nanoseconds relative to it (ouster's t), or float absolute Unix seconds
  (hesai's timestamp, recognised by its size), made relative to the header stamp; missing -> 0.
The scan's stamp is the header stamp. The simulator's ground-truth `label` is 0.
"""

from __future__ import annotations

import numpy as np

from scenarios.export import dialect
from sim.lidar import HDL32E_ELEVATION_DEG
from sim.scan import POINT_DTYPE, Scan

DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
"""sensor_msgs/PointField datatype -> numpy type."""
NAMES = {"intensity": ("intensity", "i", "reflectivity"), "ring": ("ring", "laser_id", "channel"), "time": ("time", "t", "timestamp", "timestamps")}
FOV_MARGIN_DEG = 1.0
ABSOLUTE_TIME_S = 1e6


def scan(msg, stamp: float, header_unix_s: float) -> Scan:
    """The cloud as a Scan at `stamp`; ValueError (one line) when its layout cannot be read."""
    fields = fields_dtype(msg)
    missing = [a for a in "xyz" if a not in fields.names]
    if missing:
        raise ValueError(f"PointCloud2 has no field {', '.join(missing)} (fields: {', '.join(fields.names) or 'none'})")
    height, width, step, row_step = int(msg.height), int(msg.width), int(msg.point_step), int(msg.row_step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if height * width and (row_step < width * step or data.size < height * row_step):
        raise ValueError(f"PointCloud2 data holds {data.size} bytes, too few for {height} rows of {width} points of {step} bytes")
    rows = data[: height * row_step].reshape(height, row_step)[:, : width * step] if height * width else data[:0]
    raw = np.ascontiguousarray(rows).view(fields).reshape(-1) if height * width else np.zeros(0, fields)
    xyz = np.stack([raw[a].astype(np.float64) for a in "xyz"], axis=1)
    keep = np.isfinite(xyz).all(axis=1)
    raw, xyz = raw[keep], xyz[keep]
    points = np.zeros(len(raw), POINT_DTYPE)
    for a in "xyz":
        points[a] = raw[a]
    names = {key: next((name for name in options if name in fields.names), None) for key, options in NAMES.items()}
    if names["intensity"]:
        points["intensity"] = raw[names["intensity"]]
    points["ring"] = lasers(raw, names["ring"]) if names["ring"] else rings_from_elevation(xyz)
    if names["time"]:
        points["time"] = relative_time(raw[names["time"]], header_unix_s)
    return Scan(stamp=stamp, points=points)


def lasers(raw: np.ndarray, name: str) -> np.ndarray:
    """HDL-32E laser ids of the cloud's ring field `name` (a velodyne `ring` is an elevation rank: mapped back when all are < 32)."""
    values = raw[name].astype(np.int64)
    if name == "ring" and len(values) and values.min() >= 0 and values.max() < len(dialect.LASER_OF_RING):
        return dialect.laser_of_ring(values)
    return values.astype(np.uint16)


def fields_dtype(msg) -> np.dtype:
    """The numpy layout of one point (named fields at their offsets, point_step bytes, the message's byte order)."""
    order = ">" if msg.is_bigendian else "<"
    named = [(f.name, f.offset, DATATYPES.get(int(f.datatype)), int(f.count)) for f in msg.fields]
    unknown = [name for name, _, kind, _ in named if kind is None]
    if unknown:
        raise ValueError(f"PointCloud2 field {unknown[0]!r} has an unknown datatype")
    usable = [(name, offset, kind) for name, offset, kind, count in named if count == 1 and name]
    return np.dtype(
        {
            "names": [u[0] for u in usable],
            "formats": [order + u[2] for u in usable],
            "offsets": [u[1] for u in usable],
            "itemsize": int(msg.point_step),
        }
    )


def rings_from_elevation(xyz: np.ndarray) -> np.ndarray:
    """The HDL-32E laser id nearest each point's elevation, or all 0 when the points do not fit its field of view."""
    if not len(xyz):
        return np.zeros(0, np.uint16)
    elevation = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    low, high = HDL32E_ELEVATION_DEG.min() - FOV_MARGIN_DEG, HDL32E_ELEVATION_DEG.max() + FOV_MARGIN_DEG
    if elevation.min() < low or elevation.max() > high:
        return np.zeros(len(xyz), np.uint16)
    return np.abs(elevation[:, None] - HDL32E_ELEVATION_DEG[None, :]).argmin(axis=1).astype(np.uint16)


def relative_time(values: np.ndarray, header_unix_s: float) -> np.ndarray:
    """Per-point seconds since the header stamp from a driver's time field (see the module docstring)."""
    if np.issubdtype(values.dtype, np.integer):
        return (values.astype(np.float64) * 1e-9).astype(np.float32)
    seconds = values.astype(np.float64)
    if len(seconds) and np.nanmax(np.abs(seconds)) > ABSOLUTE_TIME_S:
        seconds = seconds - header_unix_s
    return seconds.astype(np.float32)
