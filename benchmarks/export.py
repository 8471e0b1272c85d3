"""Export speed per format in scans/s on charles_river (quickstart, a 30 s stretch = 300 scans): the
whole export (simulation included, as `riverbench export` runs it: for rosbag2 and mcap with the
scenario's matchers and estimators) and, separately, writing only (the writer fed pre-simulated frames
without estimates; median over rounds). Files go to a temp dir (page cache, no fsync).

    .venv/bin/python benchmarks/export.py [--start-s 1650] [--seconds 30] [--rounds 3]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import scenarios
from scenarios.export import FORMATS, export
from scenarios.export.frames import open_stream


def main() -> None:
    """Time every registered format: a full export once, then its writer alone over the same frames."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start-s", type=float, default=1650.0)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rounds", type=int, default=3, help="rounds of the writing-only measure")
    args = parser.parse_args()
    overrides = [f"stretch={{start_s = {args.start_s}, end_s = {args.start_s + args.seconds}}}"]

    start = time.perf_counter()
    info, stream = open_stream(scenarios.load("quickstart", set=overrides))
    frames = list(stream)
    sim_s = time.perf_counter() - start
    points = sum(len(f.scan.points) for f in frames)
    print(f"quickstart {args.seconds:.0f} s from t={args.start_s:.0f} s: {len(frames)} scans, {points / len(frames):,.0f} points/scan")
    print(f"simulation only: {len(frames) / sim_s:,.0f} scans/s")
    print(f"{'format':8}{'export scans/s':>16}{'writing scans/s':>17}{'MB/scan':>9}")
    with tempfile.TemporaryDirectory(prefix="riverbench-export-") as root:
        for name, fmt in FORMATS.items():
            result = export("quickstart", name, Path(root) / f"{name}-full", set=overrides)
            size = sum(p.stat().st_size for p in result.out.rglob("*") if p.is_file())
            times = []
            for k in range(args.rounds):
                out = Path(root) / f"{name}-{k}"
                out.mkdir()
                t0 = time.perf_counter()
                fmt.write(info, iter(frames), out)
                times.append(time.perf_counter() - t0)
                shutil.rmtree(out)
            full, writing = result.scans / result.seconds, len(frames) / np.median(times)
            print(f"{name:8}{full:>16,.0f}{writing:>17,.0f}{size / result.scans / 1e6:>9.3f}")


if __name__ == "__main__":
    main()
