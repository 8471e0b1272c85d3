"""KISS-ICP's own pipeline on an exported bag against riverbench's kiss_icp matcher on the same run.

    python benchmarks/export_kiss_icp.py [--start-m 350] [--end-m 380]

Simulates canal_multipath between two route stations with the kiss_icp matcher only, exports the
same scenario to a rosbag2 bag, runs `kiss_icp_pipeline` on the bag (voxel 0.5 m as the matcher,
one thread), and prints both odometries' horizontal position error against the exact truth (lidar
position relative to the first scan, so both are compared in the same frame; horizontal because the
run's TUM files keep base_link at the waterline, z = 0, see scenarios/pipeline/files.py).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

import scenarios
from scenarios.export import export
from scenarios.export.frames import open_stream
from scenarios.pipeline.files import read_tum
from scenarios.pipeline.runner import run


def tum_poses(path: Path) -> np.ndarray:
    """(N, 4, 4) poses of a TUM file."""
    rows = read_tum(path)
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, 3] = rows[:, 1:4]
    poses[:, :3, :3] = Rotation.from_quat(rows[:, 4:8]).as_matrix()
    return poses


def errors(poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Horizontal position error of each pose (relative to its first) against the truth (relative to its first)."""
    rel = np.linalg.inv(poses[0]) @ poses
    rel_truth = np.linalg.inv(truth[0]) @ truth
    return np.linalg.norm(rel[:, :2, 3] - rel_truth[:, :2, 3], axis=1)


def describe(name: str, e: np.ndarray, moved: float) -> str:
    return f"{name:28s} rmse {np.sqrt(np.mean(e**2)):.3f} m, max {e.max():.3f} m, final {e[-1]:.3f} m over {moved:.1f} m"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--start-m", type=float, default=350.0)
    parser.add_argument("--end-m", type=float, default=380.0)
    args = parser.parse_args()
    overrides = [
        f"stretch={{start_m = {args.start_m}, end_m = {args.end_m}}}",
        'matchers=[{id = "kiss_icp", kind = "kiss_icp"}]',
        'estimators=[{id = "gps_only", kind = "gps_only"}]',
        "expect=[]",
    ]
    scenario = scenarios.load("canal_multipath", set=overrides)
    info, frames = open_stream(scenario)
    truth = np.array([f.lidar_pose for f in frames])
    mount = info.mount
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        result = run(scenario, tmp / "run", workers=1, report=False)
        ours = tum_poses(tmp / "run" / "kiss_icp.tum") @ mount  # base_link -> lidar
        export("canal_multipath", "rosbag2", tmp / "bag", set=overrides)
        config = tmp / "kiss.yaml"
        config.write_text(yaml.safe_dump({"out_dir": str(tmp / "kiss"), "mapping": {"voxel_size": 0.5}, "registration": {"max_num_threads": 1}}))
        done = subprocess.run(
            [str(Path(sys.executable).parent / "kiss_icp_pipeline"), str(tmp / "bag"), "--config", str(config)], capture_output=True, text=True
        )
        if done.returncode != 0:
            raise SystemExit(done.stderr[-2000:])
        theirs = np.load(next((tmp / "kiss" / "latest").glob("*_poses.npy")))
    moved = float(np.linalg.norm((np.linalg.inv(truth[0]) @ truth[-1])[:3, 3]))
    print(f"canal_multipath {args.start_m:g}-{args.end_m:g} m: {len(truth)} scans")
    print(describe("kiss_icp_pipeline on the bag", errors(theirs, truth), moved))
    print(describe("riverbench kiss_icp matcher", errors(ours, truth), moved))
    print(f"(the matcher's metrics.json: APE rmse {result.metrics['matchers']['kiss_icp']['ape']['rmse']:.3f} m horizontal)")


if __name__ == "__main__":
    main()
