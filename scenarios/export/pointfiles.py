"""Folders of point-cloud files, one per scan, readable by PCL, Open3D, plyfile and trimesh.

    <out>/NNNNNN.pcd or NNNNNN.ply   x y z intensity (float32, lidar frame as the sensor reports it,
                                     intensity 0-100), ring (uint16 laser id), time (float32 s since the stamp)
    <out>/times.txt                  each file's scan stamp, s (scenario time), a line per file
    <out>/poses.txt                  TUM 't x y z qx qy qz qw': the true lidar pose in world ENU at each stamp

PCD is binary v0.7 (TYPE F F F F U F, SIZE 4 4 4 4 2 4); PLY is binary little-endian with the
property types float32 and uint16 (Open3D skips the older alias "ushort").
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from scenarios.export.frames import Frame, StreamInfo
from scenarios.pipeline.files import write_tum

RECORD = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"), ("time", "<f4")])
PLY_TYPES = {"<f4": "float32", "<u2": "uint16"}
PCD_TYPES = {"<f4": ("F", 4), "<u2": ("U", 2)}


def write_pcd(info: StreamInfo, frames: Iterable[Frame], out: Path) -> dict[str, int]:
    """A binary PCD per scan plus times.txt and poses.txt; returns the counts written."""
    return _write_folder(frames, out, "pcd", pcd_header)


def write_ply(info: StreamInfo, frames: Iterable[Frame], out: Path) -> dict[str, int]:
    """A binary little-endian PLY per scan plus times.txt and poses.txt; returns the counts written."""
    return _write_folder(frames, out, "ply", ply_header)


def _write_folder(frames: Iterable[Frame], out: Path, suffix: str, header: Callable[[int], bytes]) -> dict[str, int]:
    """Write each scan as header + packed records in one go, then the stamps and poses files."""
    stamps, poses, points = [], [], 0
    for frame in frames:
        records = packed(frame.scan.points)
        (out / f"{frame.index:06d}.{suffix}").write_bytes(header(len(records)) + records.tobytes())
        stamps.append(frame.stamp)
        poses.append(frame.lidar_pose)
        points += len(records)
    np.savetxt(out / "times.txt", np.asarray(stamps), fmt="%.6f")
    write_tum(out / "poses.txt", np.asarray(stamps), np.asarray(poses).reshape(-1, 4, 4))
    return {"points": points}


def packed(points: np.ndarray) -> np.ndarray:
    """The scan's fields a sensor reports, as packed little-endian records (the truth label is left out)."""
    records = np.empty(len(points), dtype=RECORD)
    for name in RECORD.names:
        records[name] = points[name]
    return records


def pcd_header(n: int) -> bytes:
    """PCD v0.7 header for n unorganised points of RECORD, binary data."""
    fields = [PCD_TYPES[RECORD[name].str] for name in RECORD.names]
    return (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        f"FIELDS {' '.join(RECORD.names)}\n"
        f"SIZE {' '.join(str(size) for _, size in fields)}\n"
        f"TYPE {' '.join(kind for kind, _ in fields)}\n"
        f"COUNT {' '.join('1' for _ in fields)}\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    ).encode("ascii")


def ply_header(n: int) -> bytes:
    """PLY header for n vertices of RECORD, binary little-endian."""
    properties = "".join(f"property {PLY_TYPES[RECORD[name].str]} {name}\n" for name in RECORD.names)
    return f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n{properties}end_header\n".encode("ascii")
