"""The KITTI odometry layout, as KISS-ICP's kitti dataloader and the KITTI devkit read it.

    <out>/sequences/00/velodyne/NNNNNN.bin   one per scan: float32 x y z reflectance, lidar frame as
                                             the sensor reports it (no deskew), reflectance = intensity/100
    <out>/sequences/00/times.txt             seconds since the first scan, a line per scan
    <out>/sequences/00/calib.txt             P0..P3 (no camera: [I | 0]) and Tr (lidar -> camera)
    <out>/poses/00.txt                       3x4 row-major camera poses in the first camera frame

There is no camera, so the "camera" is a virtual one at the lidar with KITTI's camera axes (x right,
y down, z forward): Tr = [[0 -1 0 0] [0 0 -1 0] [1 0 0 0]]. poses/00.txt holds Tr @ P @ Tr^-1 with P
the true lidar pose in the first lidar frame, so tools in camera convention see a KITTI-like
trajectory (motion along z) and KISS-ICP's loader, which applies Tr^-1 @ pose @ Tr, gets P back.

    kiss_icp_pipeline --dataloader kitti --sequence 0 <out>       # with ground truth
    kiss_icp_pipeline <out>/sequences/00/velodyne                  # generic loader, scans untouched

KISS-ICP's kitti loader applies its 0.205 deg KITTI HDL-64 vertical-angle correction to every scan;
the generic loader reads the same files without it (but without ground truth). The kitti loader
cannot read a one-scan export (np.loadtxt makes its single pose line 1-D), and with numpy 2.4
kiss-icp 1.3's pipeline ends in a TypeError saving its TUM poses for any KITTI data (the odometry
and its metrics are done by then).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from scenarios.export.frames import Frame, StreamInfo

TR_CAM_LIDAR = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
NO_CAMERA = np.eye(4)[:3]


def write(info: StreamInfo, frames: Iterable[Frame], out: Path) -> dict[str, int]:
    """Write sequence 00 into the directory `out` scan by scan; returns the counts written."""
    sequence = out / "sequences" / "00"
    velodyne = sequence / "velodyne"
    velodyne.mkdir(parents=True)
    (out / "poses").mkdir()
    stamps, poses, points = [], [], 0
    for frame in frames:
        scan_points(frame.scan.points).tofile(velodyne / f"{frame.index:06d}.bin")
        stamps.append(frame.stamp)
        poses.append(frame.lidar_pose)
        points += len(frame.scan.points)
    write_calib(sequence / "calib.txt")
    np.savetxt(sequence / "times.txt", np.asarray(stamps) - (stamps[0] if stamps else 0.0), fmt="%.6f")
    np.savetxt(out / "poses" / "00.txt", camera_poses(np.asarray(poses).reshape(-1, 4, 4))[:, :3].reshape(-1, 12), fmt="%.12e", delimiter=" ")
    return {"points": points}


def scan_points(points: np.ndarray) -> np.ndarray:
    """(N, 4) float32 x y z reflectance, KITTI's velodyne record (reflectance in 0-1 from intensity 0-100)."""
    cloud = np.empty((len(points), 4), dtype=np.float32)
    for column, name in enumerate(("x", "y", "z")):
        cloud[:, column] = points[name]
    cloud[:, 3] = points["intensity"] / np.float32(100.0)
    return cloud


def camera_poses(lidar_poses: np.ndarray) -> np.ndarray:
    """KITTI poses.txt matrices: the virtual camera in the first camera frame, from world<-lidar poses."""
    if not len(lidar_poses):
        return lidar_poses
    relative = np.linalg.inv(lidar_poses[0]) @ lidar_poses
    return TR_CAM_LIDAR @ relative @ np.linalg.inv(TR_CAM_LIDAR)


def write_calib(path: Path) -> None:
    """calib.txt: identity projections P0..P3 (there is no camera) and Tr, 'key: 12 numbers' per line."""
    rows = {f"P{i}": NO_CAMERA for i in range(4)} | {"Tr": TR_CAM_LIDAR[:3]}
    path.write_text("".join(f"{key}: " + " ".join(f"{v:.12e}" for v in m.ravel()) + "\n" for key, m in rows.items()))
