"""Real Velodyne captures replayed with a scenario's default stack (gicp and four estimators): per capture the sensor
found, whole revolutions kept and partial ones dropped, the matcher's success, the fixes read against those in the
file, the clock offsets measured, and the realtime factor (capture duration / wall time, median over rounds) with
1 and 2 processes, and with 1 process and gicp on 2 threads (`--set matchers.gicp.params.num_threads=2`: a replay's
main process only reads packets, so gicp's second thread has a core to itself).

    .venv/bin/python benchmarks/replay_real.py [PCAP ...] [--scenario quickstart] [--rounds 3] [--setups 1x1 2x1 1x2]

--setups picks the configurations (processes x gicp threads; default all three), e.g. `--setups 2x1` for the default
stack as `riverbench replay --workers 2` runs it.

Default captures: tests/data/pcap/*.pcap (prefixes of VeloView's; the whole files are in VeloView's repository,
see tests/data/pcap/NOTICE).
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np

import scenarios
from scenarios.replay import replay

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "pcap"
SETUPS = {"1x1": (1, 1), "2x1": (2, 1), "1x2": (1, 2)}
"""Configurations by name: (processes, gicp threads)."""
TITLES = {"1x1": "1 proc", "2x1": "2 proc", "1x2": "1 proc, gicp 2 threads"}


def main() -> None:
    """Replay each capture `rounds` times with 1 and 2 processes and print one row per capture."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pcaps", nargs="*", type=Path, default=sorted(DATA.glob("*.pcap")))
    parser.add_argument("--scenario", default="quickstart")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--setups", nargs="+", choices=list(SETUPS), default=list(SETUPS), help="processes x gicp threads")
    args = parser.parse_args()
    setups = {  # (processes, gicp threads) -> the scenario
        SETUPS[name]: scenarios.load(args.scenario, set=[f"matchers.gicp.params.num_threads={SETUPS[name][1]}"]) for name in args.setups
    }
    print(f"scenario {args.scenario} (default stack); realtime factor = capture duration / wall time, median of {args.rounds}")
    head = ["capture", "sensor", "s", "scans", "dropped", "gicp ok", "fixes", "capture-sensor", "sensor-GNSS", "capture-GNSS"]
    print(" | ".join(head + [TITLES[name] for name in args.setups]))
    with tempfile.TemporaryDirectory(prefix="riverbench-real-") as root:
        for path in args.pcaps:
            factors: dict[tuple[int, int], list[float]] = {setup: [] for setup in setups}
            for (workers, threads), scenario in setups.items():
                for k in range(args.rounds):
                    out = Path(root) / f"{path.stem}-{workers}-{threads}-{k}"
                    result = replay(path, scenario, out, workers=workers, report=False)
                    factors[workers, threads].append(result.metrics["run"]["realtime_factor"])
                    shutil.rmtree(out)
            run, rec = result.metrics["run"], result.metrics["run"]["recording"]
            clocks = rec["clocks"]
            row = [
                path.name,
                rec["sensor"] + (" (bytes disagree)" if rec["sensor_note"] else ""),
                f"{run['duration_s']:.2f}",
                str(run["scans"]),
                str(rec["partial_revolutions_dropped"]),
                f"{result.metrics['matchers']['gicp']['success']:.2f}",
                f"{run['fixes']}/{rec['fixes_in_file']}",
                *(offset(clocks[key]) for key in ("capture_minus_sensor_s", "sensor_minus_gnss_s", "capture_minus_gnss_s")),
                *(f"{np.median(values):.2f}x" for values in factors.values()),
            ]
            print(" | ".join(row))


def offset(value: float | None) -> str:
    """A clock offset as printed (None: not measured)."""
    return "-" if value is None else f"{value:+.3f} s"


if __name__ == "__main__":
    main()
