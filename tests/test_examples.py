"""The examples run as the README says (slow: the sweep API they use is covered by tests/test_sweep.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.slow
# exhaustive: 271 s of CI's 2 cores at 689ae21; its calls (SweepPlan, run_sweep, rank, compare) are test_sweep's and test_report's
@pytest.mark.exhaustive
def test_the_voxel_sweep_example_ranks_three_sizes_and_writes_a_report(tmp_path):
    done = subprocess.run([sys.executable, str(EXAMPLES / "sweep_gicp_voxel.py"), str(tmp_path)], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("median") == 3 and (tmp_path / "report" / "report.html").exists()
    assert "Under bridges" in done.stdout
