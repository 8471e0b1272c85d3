"""GNSS receiver cost on a world's route: milliseconds per fix (trajectory pose, satellites, LOS and
multipath ray casts, WLS, receiver filter, truth), against the HDL-32E revolution time in the same
run, and the share GNSS adds to a run's LiDAR simulation time. Prints medians over rounds. Then each
receiver profile's open-sky horizontal CEP50 and 95% (a static antenna in open water, 1 Hz records
spread over a day) beside its datasheet figures (sim.gnss_profiles).

    .venv/bin/python benchmarks/gnss.py [--world charles_river] [--rounds 5] [--fixes 1000] [--revs 20]
                                        [--records 24] [--record-s 600]
"""

from __future__ import annotations

import argparse
import time
from datetime import timedelta

import numpy as np
import trimesh

import worlds
from sim import HDL32E, GnssReceiver, Trajectory
from sim.gnss import DEFAULT_EPOCH
from sim.gnss_profiles import PROFILES
from worlds.materials import WATER
from worlds.world import Part, World


class Still:
    """An antenna that does not move (base_link at the origin)."""

    def pose(self, t: float) -> np.ndarray:
        return np.eye(4)


def open_sky_errors(profile: str, records: int, record_s: float) -> np.ndarray:
    """Horizontal errors (m) of a static receiver in open water: `records` 1 Hz records of record_s spread over
    a day (geometry and slow errors vary), the first minute of each dropped."""
    water = trimesh.creation.box(extents=(2000.0, 2000.0, 1.0))
    water.apply_translation((0.0, 0.0, -0.5))
    base = worlds.load("open_river")
    world = World("open_sky", [Part("water", "water", WATER, water)], base.route, base.origin)
    errors = []
    for k in range(records):
        rx = GnssReceiver(rate_hz=1.0, seed=k, profile=profile, epoch_utc=DEFAULT_EPOCH + timedelta(hours=24.0 * k / records))
        for t in rx.epochs(record_s):
            fix = rx.fix(world, Still(), t)
            if t >= 60.0 and fix.quality:
                errors.append(float(np.hypot(*fix.truth.error[:2])))
    return np.asarray(errors)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--fixes", type=int, default=1000, help="fixes per round (spread along the route)")
    parser.add_argument("--revs", type=int, default=20, help="LiDAR revolutions per round")
    parser.add_argument("--records", type=int, default=24, help="open-sky records per profile (spread over a day)")
    parser.add_argument("--record-s", type=float, default=600.0, help="length of each open-sky record, s")
    args = parser.parse_args()

    world = worlds.load(args.world)
    traj = Trajectory(world)
    lidar = HDL32E()
    start = time.perf_counter()
    GnssReceiver().fix(world, traj, 0.0)  # builds the facade index and the ray-casting scene
    setup_s = time.perf_counter() - start
    lidar.scan(world, traj, 0.0)

    # Each round: one receiver driven at its output rate through 10 windows spread along the route.
    rate = GnssReceiver().rate_hz
    per_window = args.fixes // 10
    starts = np.linspace(0.0, traj.duration - per_window / rate - 1.0, 10)
    times = (starts[:, None] + np.arange(per_window) / rate).ravel()
    start = time.perf_counter()
    for t in times:
        traj.pose(t)
    pose_ms = (time.perf_counter() - start) / len(times) * 1e3
    stamps = np.linspace(0.0, traj.duration - 1.0, args.rounds * args.revs).reshape(args.rounds, args.revs)
    fix_ms, rev_ms = [], []
    for r in range(args.rounds):
        rx = GnssReceiver(seed=r)
        rx.fix(world, traj, times[0])  # per-world cache
        start = time.perf_counter()
        for t in times[1:]:
            rx.fix(world, traj, t)
        fix_ms.append((time.perf_counter() - start) / (len(times) - 1) * 1e3)
        start = time.perf_counter()
        for t0 in stamps[r]:
            lidar.scan(world, traj, float(t0))
        rev_ms.append((time.perf_counter() - start) / args.revs * 1e3)

    gnss, rev = float(np.median(fix_ms)), float(np.median(rev_ms))
    rx = GnssReceiver()
    share = rx.rate_hz * gnss / (lidar.config.rate_hz * rev)
    print(f"world {args.world}: {len(world.mesh.faces)} triangles; facade index + scene build {setup_s:.2f} s")
    print(
        f"GNSS fix:            {gnss:.3f} ms (median of {args.rounds} rounds x {len(times) - 1} fixes at "
        f"{rate:g} Hz, incl. trajectory.pose; rounds {', '.join(f'{m:.3f}' for m in fix_ms)})"
    )
    print(f"  of which trajectory.pose(t): {pose_ms:.3f} ms (the receiver asks for one pose per fix)")
    print(f"HDL-32E revolution:  {rev:.2f} ms (median of {args.rounds} rounds x {args.revs} revolutions)")
    print(f"GNSS at {rx.rate_hz:g} Hz adds {100 * share:.2f}% to LiDAR at {lidar.config.rate_hz:g} Hz (target < 5%)")
    print(f"open-sky horizontal error, static antenna, {args.records} x {args.record_s:g} s at 1 Hz over a day:")
    for name, profile in PROFILES.items():
        errors = open_sky_errors(name, args.records, args.record_s)
        cep50, p95 = float(np.median(errors)), float(np.percentile(errors, 95))
        print(
            f"  {name:9s} CEP50 {cep50:.3f} m (datasheet {profile.cep50_m:.3f})  95% {p95:.3f} m (datasheet {profile.p95_m:.3f})"
            f"  [{profile.receiver}]"
        )


if __name__ == "__main__":
    main()
