"""How far a LiDAR's rough returns repeat from one revolution to the next, standing still: a real HDL-32E (the Monterey
capture in tests/data/pcap, a stationary vehicle) beside the simulated one over charles_river's tree-lined basin with
each foliage echo model (sim.lidar's foliage_echo: 'facets', 'leaves').

A return is rough when its range departs from the line through its two azimuth neighbours on the same ring (a crown's
leaves, a depth edge); for every return of a revolution the script finds the previous revolution's return of the same
laser within 0.1 deg of azimuth and prints, by roughness class, the median range change and the share beyond 0.3 m.
A surface repeats (centimetres); a crown whose every echo is drawn afresh ('leaves') does not.

    .venv/bin/python benchmarks/foliage_echo.py [--station 1000] [--revolutions 7]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import velodyne_decoder as vd

import worlds
from sim import HDL32E, Trajectory

PCAP = Path(__file__).resolve().parents[1] / "tests" / "data" / "pcap" / "monterey-hdl32e-prefix.pcap"
CLASSES = ((0.0, 0.05), (0.05, 0.3), (0.3, 1.0), (1.0, np.inf))
"""Roughness classes, m."""


def columns(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth (deg), range (m) and ring of structured points with x, y, z, ring."""
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(float)
    return np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0])) % 360.0, np.linalg.norm(xyz, axis=1), points["ring"].astype(int)


def roughness(az: np.ndarray, r: np.ndarray, ring: np.ndarray, gap_deg: float = 0.5) -> np.ndarray:
    """|range - the range interpolated between the azimuth neighbours on the same ring| (NaN without both within gap_deg)."""
    o = np.lexsort((az, ring))
    a, rr, g = az[o], r[o], ring[o]
    ok = (g[:-2] == g[1:-1]) & (g[2:] == g[1:-1]) & (a[1:-1] - a[:-2] < gap_deg) & (a[2:] - a[1:-1] < gap_deg) & (a[2:] > a[:-2])
    expected = rr[:-2] + (rr[2:] - rr[:-2]) * (a[1:-1] - a[:-2]) / np.where(ok, a[2:] - a[:-2], 1.0)
    out = np.full(len(r), np.nan)
    out[o[1:-1]] = np.where(ok, np.abs(rr[1:-1] - expected), np.nan)
    return out


def range_change(prev: np.ndarray, cur: np.ndarray, max_deg: float = 0.1) -> np.ndarray:
    """|range change| of each of cur's returns from prev's return of the same laser nearest in azimuth (NaN beyond max_deg)."""
    (pa, pr, pg), (ca, cr, cg) = columns(prev), columns(cur)
    out = np.full(len(cr), np.nan)
    for ring in np.unique(cg):
        ip, ic = np.flatnonzero(pg == ring), np.flatnonzero(cg == ring)
        if len(ip) < 2:
            continue
        ip = ip[np.argsort(pa[ip])]
        j = np.clip(np.searchsorted(pa[ip], ca[ic]), 1, len(ip) - 1)
        near = np.where(np.abs(pa[ip[j - 1]] - ca[ic]) < np.abs(pa[ip[j]] - ca[ic]), ip[j - 1], ip[j])
        close = np.abs(pa[near] - ca[ic]) < max_deg
        out[ic[close]] = np.abs(cr[ic[close]] - pr[near[close]])
    return out


def table(name: str, revolutions: list[np.ndarray]) -> None:
    """Print the repeatability by roughness class over consecutive revolutions (returns 5-80 m away)."""
    rough, change = [], []
    for prev, cur in zip(revolutions, revolutions[1:]):
        az, r, ring = columns(cur)
        keep = (r > 5.0) & (r < 80.0)
        rough.append(roughness(az, r, ring)[keep])
        change.append(range_change(prev, cur)[keep])
    rgh, chg = np.concatenate(rough), np.concatenate(change)
    judged = np.isfinite(rgh) & np.isfinite(chg)
    print(f"{name}: {len(revolutions)} revolutions, {judged.sum()} returns judged")
    for lo, hi in CLASSES:
        cls = judged & (rgh >= lo) & (rgh < hi)
        print(
            f"  roughness {lo:g}-{hi:g} m: {cls.sum() / judged.sum():6.1%} of returns; range change median "
            f"{np.median(chg[cls]):.3f} m, beyond 0.3 m {np.mean(chg[cls] > 0.3):5.1%}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--station", type=float, default=1000.0, help="charles_river route station of the simulated sensor, m")
    parser.add_argument("--revolutions", type=int, default=7)
    args = parser.parse_args()
    config = vd.Config(model=vd.Model.HDL32E)
    real = [s.points for s in vd.read_pcap(str(PCAP), config, as_pcl_structs=True)][:-1]  # the last revolution is cut short
    table(f"real HDL-32E, stationary ({PCAP.name})", real[: args.revolutions])
    world = worlds.load("charles_river")
    still = Trajectory(world, speed_mps=0.001, start_m=args.station)
    for mode in ("facets", "leaves"):
        lidar = HDL32E(foliage_echo=mode)
        sim = [lidar.scan(world, still, 1.0 + k * lidar.revolution_s).points for k in range(args.revolutions)]
        table(f"simulated, stationary at station {args.station:g} m, foliage_echo={mode}", sim)


if __name__ == "__main__":
    main()
