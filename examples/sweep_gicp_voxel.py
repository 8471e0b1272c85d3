"""Tune gicp's voxel size under the Harvard Bridge: a sweep over 3 voxel sizes x 2 seeds from Python,
the best size by the ekf's worst error in the blackout, then the comparison report of the sweep.

    .venv/bin/python examples/sweep_gicp_voxel.py [OUT_DIR]      # about a minute on 2 cores

The same from the command line:
    riverbench sweep harvard_beam_bridge --grid matchers.gicp.params.voxel_m=0.2,0.4,0.8 --seeds 2 \\
        --set "stretch={start_m = 1620.0, end_m = 1720.0}" --objective estimators.ekf.windows.blackout.max_error
    riverbench report runs/sweep-<time>
"""

from __future__ import annotations

import sys
from pathlib import Path

from scenarios.batch.plan import Axis, SweepPlan
from scenarios.batch.sweep import check_metric, rank, run_sweep
from scenarios.report import compare

OBJECTIVE = "estimators.ekf.windows.blackout.max_error"


def main(out: Path) -> None:
    plan = SweepPlan(
        ("harvard_beam_bridge",),
        grid=(Axis.parse("matchers.gicp.params.voxel_m=0.2,0.4,0.8"),),
        seeds=2,
        fixed=("stretch={start_m = 1620.0, end_m = 1720.0}",),
    )
    points = plan.points()
    check_metric(OBJECTIVE, points)
    result = run_sweep(
        plan,
        out / "sweep",
        workers=2,
        lean=True,
        points=points,
        on_row=lambda r: print(
            f"{r['status']}: voxel {r['param.matchers.gicp.params.voxel_m']} m, seed {r['seed']}, "
            f"ekf blackout max {r.get(OBJECTIVE, float('nan')):.2f} m"
        ),
    )
    for group in rank(result.rows, OBJECTIVE):
        seeds = ", ".join(f"{v:.2f}" for v in group.values)
        print(f"voxel {group.params['matchers.gicp.params.voxel_m']} m: median {group.median:.2f} m (seeds: {seeds})")
    page = compare.write([out / "sweep"], out / "report")
    print("\n".join(compare.summary_sentences([out / "sweep"])))
    print(f"results: {out / 'sweep' / 'results.parquet'}; report: {page}")


if __name__ == "__main__":  # the sweep's workers are spawned processes: the guard is required
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs/example-voxel"))
