"""Replay speed against real time (recording duration / wall time) on a canal_multipath stretch exported to
rosbag2, mcap and pcap: reading alone (scans and fixes decoded, nothing run) and the whole replay of the
scenario's default stack (gicp and four estimators), with 1 and 2 processes; median over rounds.

    .venv/bin/python benchmarks/replay.py [--start-s 120] [--seconds 10] [--rounds 3]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import scenarios
import worlds
from scenarios.export import export
from scenarios.replay import replay
from scenarios.replay.recording import Place
from scenarios.replay.run import open_recording

FORMATS = {"rosbag2": "bag", "mcap": "mcap", "pcap": "run.pcap"}


def main() -> None:
    """Export the stretch once per format, then time reading and replaying each."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start-s", type=float, default=120.0)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    overrides = [f"stretch={{start_s = {args.start_s}, end_s = {args.start_s + args.seconds}}}"]
    scenario = scenarios.load("canal_multipath", set=overrides)
    world = worlds.load(scenario.world, **scenario.world_params)
    place = Place(tuple(world.origin), scenario.gnss.epoch_utc, scenario.lidar.start_azimuth_deg)
    print(f"canal_multipath {args.seconds:.0f} s from t={args.start_s:.0f} s, default stack; realtime factors (median of {args.rounds})")
    print(f"{'format':8}{'MB':>8}{'reading':>10}{'1 process':>11}{'2 processes':>13}")
    with tempfile.TemporaryDirectory(prefix="riverbench-replay-") as root:
        for fmt, name in FORMATS.items():
            recording = Path(root) / name
            export("canal_multipath", fmt, recording, set=overrides)
            size = sum(p.stat().st_size for p in ([recording] if recording.is_file() else recording.rglob("*")))
            reading = []
            for _ in range(args.rounds):
                t0 = time.perf_counter()
                for _event in open_recording(recording, place, None, None).events():
                    pass
                reading.append(args.seconds / (time.perf_counter() - t0))
            factors = {}
            for workers in (1, 2):
                factors[workers] = []
                for k in range(args.rounds):
                    out = Path(root) / f"out-{fmt}-{workers}-{k}"
                    result = replay(recording, scenario, out, workers=workers, report=False)
                    factors[workers].append(result.metrics["run"]["realtime_factor"])
                    shutil.rmtree(out)
            print(f"{fmt:8}{size / 1e6:>8.1f}{np.median(reading):>9.1f}x{np.median(factors[1]):>10.1f}x{np.median(factors[2]):>12.1f}x")


if __name__ == "__main__":
    main()
