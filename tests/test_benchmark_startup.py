"""benchmarks/startup.py against exact answers: a run directory written with files.write_tum (the run's own writer)
whose estimator starts 5 s in, 1 m and 2 deg off, and whose matcher odometry covered half of each true step."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from scenarios.pipeline.files import write_tum

ROOT = Path(__file__).resolve().parent.parent
ZERO_NS = 1_532_876_400_000_000_000


def _script():
    spec = importlib.util.spec_from_file_location("startup_script", ROOT / "benchmarks" / "startup.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _poses(xy: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    poses = np.tile(np.eye(4), (len(xy), 1, 1))
    poses[:, 0, 0] = poses[:, 1, 1] = np.cos(yaw)
    poses[:, 1, 0], poses[:, 0, 1] = np.sin(yaw), -np.sin(yaw)
    poses[:, :2, 3] = xy
    return poses


@pytest.fixture
def run(tmp_path: Path) -> Path:
    t = 100.0 + 0.1 * np.arange(201)  # 20 s of scans from scenario time 100 s
    heading = math.radians(30.0)
    along = 2.0 * (t - t[0])
    xy = np.column_stack([along * math.cos(heading), along * math.sin(heading)])
    yaw = np.full(len(t), heading)
    write_tum(tmp_path / "groundtruth.tum", t, _poses(xy, yaw), ZERO_NS)
    write_tum(tmp_path / "gicp.tum", t, _poses(0.5 * xy, yaw), ZERO_NS)  # half of each step
    started = t >= 105.0
    offset = np.array([-math.sin(heading), math.cos(heading)])  # 1 m to the left
    est = _poses(xy + offset, yaw + math.radians(2.0))
    est[~started] = np.nan  # not initialised yet: no row
    write_tum(tmp_path / "ekf.tum", t, est, ZERO_NS)
    (tmp_path / "scenario.toml").write_text(
        'name = "startup"\nseed = 4\n[[estimators]]\nid = "ekf"\nmatcher = "gicp"\n[[estimators]]\nid = "late"\nmatcher = "gicp"\n'
    )
    write_tum(tmp_path / "late.tum", t, np.full((len(t), 4, 4), np.nan), ZERO_NS)  # never initialised
    return tmp_path


def test_the_start_its_errors_and_the_share_of_the_travel_the_odometry_measured(run):
    rows = _script().starts(run, window_s=3.0)
    assert rows == [
        "| startup seed 4 | ekf | 105.0 | 5.0 | 1.00 | +2.0 | 0.50 |",
        "| startup seed 4 | late | never | | | | |",
    ]


def test_a_directory_without_a_scenario_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["startup.py", str(tmp_path)])
    assert _script().main() == 2
    assert capsys.readouterr().err.strip() == f"error: not a run directory (no scenario.toml): {tmp_path}"


def test_a_corrupt_file_of_a_run_is_one_line_and_exit_2(run, capsys, monkeypatch):
    (run / "gicp.tum").write_text("# timestamp tx ty tz qx qy qz qw\n1532876500.0 1 2 3\n")  # a truncated row
    monkeypatch.setattr("sys.argv", ["startup.py", str(run)])
    assert _script().main() == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {run}: ValueError:") and "\n" not in err
