"""GNSS along a world's route: blackout and NLOS shares, horizontal error against HDOP, and a plot of
error and HDOP against time (PNG). One receiver at its default settings (5 Hz, internal filter)
plus the same receiver's raw solutions, both driven along the whole route.

    .venv/bin/python benchmarks/gnss_route.py [--world charles_river] [--seed 0] [--out benchmarks/out]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import worlds
from sim import GnssReceiver, Trajectory


def run(world, traj, seed: int, mode: str) -> dict[str, np.ndarray]:
    """Drive one receiver along the route; per-epoch arrays of what the statistics need."""
    rx = GnssReceiver(seed=seed, filter_mode=mode)
    t = rx.epochs(traj.duration)
    fixes = [rx.fix(world, traj, ti) for ti in t]
    used_nlos = [sum(tr.nlos for tr, s in zip(f.truth.sats, f.sats) if s.used) for f in fixes]
    return {
        "t": t,
        "quality": np.array([f.quality for f in fixes]),
        "num_sats": np.array([f.num_sats for f in fixes]),
        "hdop": np.array([f.hdop for f in fixes]),
        "herr": np.array([np.hypot(*f.truth.error[:2]) for f in fixes]),
        "used_nlos": np.array(used_nlos),
        "tracked": np.array([sum(s.snr > 0 for s in f.sats) for f in fixes]),
        "station": np.array([world.route.station_of(f.truth.enu[:2]) for f in fixes]),
    }


def statistics(r: dict[str, np.ndarray]) -> dict[str, float]:
    """Shares and error figures of one run (errors over epochs with a reported position)."""
    valid = r["quality"] != 0
    raw = r["num_sats"] > 0
    herr = r["herr"][valid]
    with_hdop = valid & raw
    big = r["herr"] > 10.0
    return {
        "epochs": len(r["t"]),
        "blackout_share": float(np.mean(~raw)),
        "coast_share": float(np.mean(r["quality"] == 6)),
        "invalid_share": float(np.mean(r["quality"] == 0)),
        "nlos_epoch_share": float(np.mean(r["used_nlos"][raw] > 0)),
        "nlos_sat_share": float(r["used_nlos"].sum() / max(r["num_sats"].sum(), 1)),
        "herr_median": float(np.median(herr)),
        "herr_p95": float(np.percentile(herr, 95)),
        "herr_max": float(herr.max()),
        "corr_herr_hdop": float(np.corrcoef(r["herr"][with_hdop], r["hdop"][with_hdop])[0, 1]),
        "big_errors": int((big & with_hdop).sum()),
        "big_errors_hdop_lt2_share": float(((big & (r["hdop"] < 2.0)).sum()) / max((big & with_hdop).sum(), 1)),
    }


def plot(r: dict[str, np.ndarray], raw: dict[str, np.ndarray], world_name: str, path: Path) -> None:
    """Horizontal error (filtered and raw) and HDOP against time; blackouts and NLOS epochs marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_err, ax_hdop) = plt.subplots(2, 1, figsize=(14, 7), sharex=True, height_ratios=[3, 1.3])
    t = r["t"]
    blackout = r["num_sats"] == 0
    for ax in (ax_err, ax_hdop):
        ax.fill_between(t, 0, 1, where=blackout, transform=ax.get_xaxis_transform(), color="0.8", lw=0, label="no raw fix (blackout)")
    ax_err.plot(t, raw["herr"], lw=0.5, color="tab:orange", alpha=0.7, label="raw WLS solution")
    ax_err.plot(t, r["herr"], lw=0.9, color="tab:blue", label="receiver output (internal filter)")
    coast = r["quality"] == 6
    ax_err.scatter(t[coast], r["herr"][coast], s=4, color="tab:purple", zorder=3, label="dead reckoning (quality 6)")
    nlos = r["used_nlos"] > 0
    ax_err.scatter(t[nlos], np.full(nlos.sum(), -1.0), s=2, marker="|", color="tab:red", label="NLOS satellite used")
    ax_err.set_ylabel("horizontal error (m)")
    ax_err.set_yscale("symlog", linthresh=10.0, linscale=2.0)
    ax_err.set_yticks([0, 2, 4, 6, 8, 10, 20, 50, 100])
    ax_err.set_yticklabels(["0", "2", "4", "6", "8", "10", "20", "50", "100"])
    ax_err.axhline(10.0, color="k", lw=0.5, ls=":")
    ax_err.legend(loc="upper right", fontsize=8, ncols=3)
    ax_err.set_title(f"GNSS along {world_name}: horizontal error and HDOP (5 Hz, default receiver)")
    ax_hdop.plot(t, r["hdop"], lw=0.8, color="tab:green")
    ax_hdop.axhline(2.0, color="k", lw=0.5, ls=":")
    ax_hdop.set_ylabel("HDOP")
    ax_hdop.set_ylim(0, min(10.0, np.nanmax(r["hdop"]) * 1.1))
    ax_hdop.set_xlabel("time since start (s)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=110)
    tmp.replace(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/out"))
    args = parser.parse_args()

    world = worlds.load(args.world)
    traj = Trajectory(world)
    filtered = run(world, traj, args.seed, "kalman")
    raw = run(world, traj, args.seed, "raw")
    print(f"world {args.world}: route {world.route.length:.0f} m, {traj.duration:.0f} s at 5 Hz")
    for name, r in (("filtered", filtered), ("raw", raw)):
        s = statistics(r)
        print(
            f"{name:>8}: epochs {s['epochs']}, blackout (no raw fix) {100 * s['blackout_share']:.2f}%, "
            f"dead reckoning {100 * s['coast_share']:.2f}%, invalid {100 * s['invalid_share']:.2f}%, "
            f"epochs using NLOS {100 * s['nlos_epoch_share']:.2f}% (of used satellites {100 * s['nlos_sat_share']:.2f}%)"
        )
        print(
            f"{'':>8}  horizontal error median {s['herr_median']:.2f} m, p95 {s['herr_p95']:.2f} m, "
            f"max {s['herr_max']:.1f} m; corr(error, HDOP) {s['corr_herr_hdop']:.2f}; errors > 10 m: "
            f"{s['big_errors']}, of which HDOP < 2: {100 * s['big_errors_hdop_lt2_share']:.0f}%"
        )
    path = args.out / f"gnss_route_{args.world}.png"
    plot(filtered, raw, args.world, path)
    print(f"plot: {path}")


if __name__ == "__main__":
    main()
