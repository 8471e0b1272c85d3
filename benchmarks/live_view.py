"""What the live view costs a run: `riverbench run SCENARIO --fast` with and without `--view-save`, interleaved.

Each run is its own process (`--no-report --quiet`); the figures are the run's metrics.json
`run.realtime_factor` (simulated over wall time, world load to last scan) and the CPU seconds of the
run's processes (user + system, what the view adds whatever else the machine is doing), medians
over the repeats, and the recording's size per scan. Target: with the view the run keeps at least
real time.

    .venv/bin/python benchmarks/live_view.py [--scenario quickstart] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def measure(scenario: str, view: bool) -> dict:
    """One run in a fresh process: its realtime factor, scans, CPU seconds and (with the view) recording bytes."""
    with tempfile.TemporaryDirectory() as tmp:
        out, rrd = Path(tmp) / "run", Path(tmp) / "view.rrd"
        cmd = [sys.executable, "-m", "scenarios.cli", "run", scenario, "--fast", "--out", str(out), "--no-report", "--quiet"]
        cmd += ["--view-save", str(rrd)] if view else []
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(cmd, capture_output=True, text=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode not in (0, 1):
            raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr.strip() or done.stdout.strip()}")
        run = json.loads((out / "metrics.json").read_text())["run"]
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        return {"rtf": run["realtime_factor"], "scans": run["scans"], "cpu_s": cpu, "bytes": rrd.stat().st_size if view else 0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="quickstart")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    runs: dict[bool, list[dict]] = {False: [], True: []}
    print(f"riverbench run {args.scenario} --fast [--view-save], {args.repeats} of each, interleaved")
    print(f"{'view':>5} {'x real time':>11} {'CPU s':>7} {'scans':>6} {'KB per scan':>11}")
    for _ in range(args.repeats):
        for view in (False, True):
            r = measure(args.scenario, view)
            runs[view].append(r)
            print(f"{'yes' if view else 'no':>5} {r['rtf']:>11.2f} {r['cpu_s']:>7.1f} {r['scans']:>6} {r['bytes'] / r['scans'] / 1e3:>11.1f}")
    rtf = {v: statistics.median(r["rtf"] for r in rs) for v, rs in runs.items()}
    cpu = {v: statistics.median(r["cpu_s"] for r in rs) for v, rs in runs.items()}
    print(f"median x real time: without {rtf[False]:.2f}, with --view-save {rtf[True]:.2f} (ratio {rtf[True] / rtf[False]:.2f}; target >= 1.0 with)")
    added = cpu[True] - cpu[False]
    print(f"median CPU s: without {cpu[False]:.1f}, with {cpu[True]:.1f} (+{added:.1f} s, {1e3 * added / runs[True][0]['scans']:.1f} ms per scan)")


if __name__ == "__main__":
    main()
