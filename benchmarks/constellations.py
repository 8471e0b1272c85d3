"""GPS only against GPS + GLONASS + Galileo + BeiDou: satellites visible and used, blackouts, NLOS errors.

The receiver alone (no LiDAR) at its defaults, driven along the library's GNSS stretches: the charles_river bridges
(bu_truss_bridge, harvard_beam_bridge, longfellow_arch_bridge), canal_multipath's canyon, and a sample of the whole
charles_river route (150 m every 1000 m). Per case and constellation set: medians of the satellites above the mask
with an ephemeris ("visible") and used in the fix, the outages (stretches without a measured fix, GGA quality none of 1, 2, 4, 5:
the receiver dead-reckons (6) for up to 10 s, then reports none (0); their count, median and longest, s), the
longest stretch of quality 0 (s), the share of fixes using an NLOS satellite (truth), and the horizontal error of those fixes (p50, p95, m).

    .venv/bin/python benchmarks/constellations.py [--seed 0] [--rate 5]
"""

from __future__ import annotations

import argparse

import numpy as np

import worlds
from fusion.observation import POSITION_QUALITIES
from sim import GnssReceiver, Trajectory

SETS = {"GPS": ["GPS"], "GPS+GLO+GAL+BDS": ["GPS", "GLONASS", "GALILEO", "BEIDOU"]}
CASES = {
    "bu_truss_bridge": ("charles_river", [(0.0, 240.0)]),
    "harvard_beam_bridge": ("charles_river", [(1620.0, 1800.0)]),
    "longfellow_arch_bridge": ("charles_river", [(3100.0, 3320.0)]),
    "canal_multipath": ("canal_lock", [(170.0, 420.0)]),
    "charles_river sample": ("charles_river", [(s, s + 150.0) for s in (500.0, 1500.0, 2500.0, 3500.0, 4500.0)]),
}


def drive(world, stretches, constellations, seed: int, rate_hz: float) -> dict[str, np.ndarray]:
    """Per-epoch figures of one receiver over each stretch (a fresh receiver per stretch, as a scenario starts one)."""
    rows: dict[str, list] = {"visible": [], "used": [], "quality": [], "nlos": [], "herr": [], "piece": []}
    for k, (start_m, end_m) in enumerate(stretches):
        trajectory = Trajectory(world, start_m=start_m, end_m=end_m)
        rx = GnssReceiver(seed=seed, rate_hz=rate_hz, constellations=constellations)
        for t in rx.epochs(trajectory.duration):
            fix = rx.fix(world, trajectory, t)
            rows["visible"].append(len(fix.sats))
            rows["used"].append(fix.num_sats)
            rows["quality"].append(fix.quality)
            rows["nlos"].append(fix.quality in POSITION_QUALITIES and any(s.used and tr.nlos for s, tr in zip(fix.sats, fix.truth.sats, strict=True)))
            rows["herr"].append(float(np.hypot(*fix.truth.error[:2])))
            rows["piece"].append(k)
    return {key: np.array(value) for key, value in rows.items()}


def runs(flag: np.ndarray, piece: np.ndarray, rate_hz: float) -> list[float]:
    """Lengths (s) of the runs of flagged epochs within each stretch."""
    out = []
    for k in np.unique(piece):
        invalid = np.r_[False, flag[piece == k], False].astype(int)
        edges = np.flatnonzero(np.diff(invalid))
        out += ((edges[1::2] - edges[::2]) / rate_hz).tolist()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rate", type=float, default=5.0, help="receiver rate, Hz")
    args = parser.parse_args()
    print(f"seed {args.seed}, {args.rate:g} Hz, default epoch and ephemeris (sim.gnss.DEFAULT_EPOCH)")
    widths = {"visible": 7, "used": 5, "outages": 7, "median s": 8, "max s": 6, "q0 max s": 8, "NLOS fixes": 10, "NLOS p50": 8, "p95 m": 6}
    print(f"{'case':24s} {'systems':16s} " + " ".join(f"{name:>{width}s}" for name, width in widths.items()))
    for case, (world_name, stretches) in CASES.items():
        world = worlds.load(world_name)
        for label, constellations in SETS.items():
            r = drive(world, stretches, constellations, args.seed, args.rate)
            outages = runs(~np.isin(r["quality"], sorted(POSITION_QUALITIES)), r["piece"], args.rate)
            invalid = runs(r["quality"] == 0, r["piece"], args.rate)
            nlos_err = r["herr"][r["nlos"]]
            p50, p95 = np.percentile(nlos_err, [50, 95]) if len(nlos_err) else (np.nan, np.nan)
            print(
                f"{case:24s} {label:16s} {np.median(r['visible']):7.0f} {np.median(r['used']):5.0f} {len(outages):7d} "
                f"{np.median(outages) if outages else 0.0:8.1f} {max(outages, default=0.0):6.1f} {max(invalid, default=0.0):8.1f} "
                f"{r['nlos'].mean():10.3f} {p50:8.1f} {p95:6.1f}"
            )


if __name__ == "__main__":
    main()
