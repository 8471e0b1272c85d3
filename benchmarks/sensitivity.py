"""How far one lost LiDAR return moves a run's metrics, against the spread over seeds the regression check judges by.

Each scenario's [fast] variant runs twice on one seed: as is, and with a single return dropped from the revolution
nearest the middle of the stretch (its farthest point: physically nothing, one drop-out among tens of thousands).
For each estimator's and matcher's headline metrics it prints both values, the move, and the move as a share of the
range over the seeds stored in the baseline (`benchmarks/baseline/library.json`). A share near 1 means a change that
touches a single point can look like a regression of the whole seed spread, and a real one can hide in that noise.

    .venv/bin/python benchmarks/sensitivity.py [SCENARIO ...] [--seed 0] [--baseline benchmarks/baseline/library.json]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

import scenarios
import sim
from scenarios.score.baseline import flatten, load
from scenarios.spec.library import load_fast
from sim.scan import Scan

BASELINE = Path(__file__).resolve().parent / "baseline" / "library.json"
METRICS = ("ape.p95", "ape.max", "yaw.p95", "windows.blackout.max_error")


def run(name: str, seed: int, out: Path, drop_at: float | None) -> dict:
    """The metrics tree of the [fast] run of `name`; with drop_at, the revolution starting nearest it loses its farthest return."""
    spec = load_fast(name, seed=seed)
    original = sim.HDL32E.scan

    def scan(self, world, trajectory, t0):
        result = original(self, world, trajectory, t0)
        if drop_at is None or abs(t0 - drop_at) > 0.5 / self.config.rate_hz or not len(result.points):
            return result
        p = result.points
        farthest = int(np.argmax(p["x"].astype(float) ** 2 + p["y"].astype(float) ** 2 + p["z"].astype(float) ** 2))
        return Scan(stamp=result.stamp, points=np.delete(p, farthest))

    sim.HDL32E.scan = scan  # the LiDAR runs in this process (the matcher pool gets the scans it produced)
    try:
        return scenarios.run(spec, out, workers=1, report=False).metrics
    finally:
        sim.HDL32E.scan = original


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=["charles_river", "quickstart", "chase_boat"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--baseline", type=Path, default=BASELINE)
    args = parser.parse_args()
    try:
        stored = load(args.baseline).scenarios
        for name in args.scenarios:
            load_fast(name)  # an unknown scenario or one without a [fast] variant: refused before anything runs
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print("| scenario [fast] | seed | metric | as is | one return dropped | move | range over the baseline's seeds | move / range |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="riverbench-sensitivity-") as root:
        for name in args.scenarios:
            as_is = run(name, args.seed, Path(root) / f"{name}-as-is", None)
            middle = 0.5 * (as_is["run"]["t_start"] + as_is["run"]["t_end"])
            before, after = flatten(as_is), flatten(run(name, args.seed, Path(root) / f"{name}-dropped", middle))
            seeds = stored[name].metrics if name in stored else {}
            for key, value in before.items():
                if value is None or not key.startswith(("estimators.", "matchers.")) or key.split(".", 2)[2] not in METRICS:
                    continue
                values = [v for v in seeds.get(key, []) if v is not None]
                spread = max(values) - min(values) if len(values) > 1 else math.nan
                moved = after.get(key)
                move = math.nan if moved is None else moved - value
                share = abs(move) / spread if spread > 0 else math.nan
                label = key.replace("estimators.", "").replace("matchers.", "")
                cells = [name, str(args.seed), label, f"{value:.3g}", f"{value + move:.3g}", f"{move:+.3g}", f"{spread:.3g}"]
                print("| " + " | ".join([*cells, f"{share:.2f}"]) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
