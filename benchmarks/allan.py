"""Allan deviation of each IMU preset at rest: writes a log-log plot (PNG) and prints the datasheet figures beside
the ones read back from the simulated sensor (noise density from the -1/2 slope around tau = 1 s, bias instability
as the floor / 0.664, IEEE Std 952), and what simulating 100 Hz costs per second of run.

    .venv/bin/python benchmarks/allan.py [--out allan.png] [--units 8]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import allantools
import numpy as np

from riverbench.atomic import atomic_path
from sim.imu import STANDARD_GRAVITY, Imu, ImuConfig
from sim.plane_motion import PlaneMotion
from sim.waves import WaveMotion

RECORD_S = {"mti630": 20000.0, "bmi088": 200000.0}
"""Record length per preset: ten times the end of its Allan floor."""


class AtRest:
    """A vessel moored still and level."""

    waves = WaveMotion(omega=np.zeros(1), phase=np.zeros(1), heave_amp=np.zeros(1), roll_amp=np.zeros(1), pitch_amp=np.zeros(1))

    def plane_motion(self, ts: np.ndarray) -> PlaneMotion:
        z = np.zeros(len(ts))
        return PlaneMotion(np.zeros((len(ts), 2)), z, np.zeros((len(ts), 2)), np.zeros((len(ts), 2)), z)


def record(preset: str, rate_hz: float, duration_s: float, units: int, **overrides) -> tuple[np.ndarray, np.ndarray]:
    """(gyro, accel) of `units` parts at rest, each axis of each unit a column."""
    gyro, accel = [], []
    for unit in range(units):
        imu = Imu(ImuConfig(preset=preset, rate_hz=rate_hz, **overrides), seed=unit)
        parts = [imu.sample(AtRest(), imu.times(t, min(t + 20000.0, duration_s))) for t in np.arange(0.0, duration_s, 20000.0)]
        gyro.append(np.concatenate([p.gyro for p in parts]))
        accel.append(np.concatenate([p.accel for p in parts]))
    return np.hstack(gyro), np.hstack(accel)


def adev(data: np.ndarray, rate: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation (allantools), averaged as a variance over the columns."""
    out = [allantools.oadev(data[:, k], rate=rate, data_type="freq", taus=taus) for k in range(data.shape[1])]
    return out[0][0], np.sqrt(np.mean([o[1] ** 2 for o in out], axis=0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("allan.png"))
    parser.add_argument("--units", type=int, default=8, help="simulated parts averaged per preset")
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    print(f"{'preset':8s} {'sensor':6s} {'figure':22s} {'datasheet':>10s} {'read back':>10s} {'ratio':>6s}")
    for preset in ("mti630", "bmi088"):
        cfg = ImuConfig(preset=preset)
        fast_g, fast_a = record(preset, 100.0, 600.0, 2)
        duration = RECORD_S[preset]
        # 1 Hz for the long record: the floor lies at tau >> 1 s; the LSB is off there (at 1 Hz it would add its own white noise)
        slow_g, slow_a = record(preset, 1.0, duration, args.units, gyro={"resolution_dps": 0.0}, accel={"resolution_ug": 0.0})
        for sensor, fast, slow, unit, scale, density, instability in (
            ("gyro", fast_g, slow_g, "deg/s", math.degrees(1.0), cfg.gyro.noise_density_dps, cfg.gyro.bias_instability_dph),
            ("accel", fast_a, slow_a, "ug", 1e6 / STANDARD_GRAVITY, cfg.accel.noise_density_ug, cfg.accel.bias_instability_ug),
        ):
            t_fast, a_fast = adev(fast, 100.0, np.logspace(-2, 1, 31))
            t_slow, a_slow = adev(slow, 1.0, np.logspace(0, math.log10(duration / 8), 40))
            keep = (t_fast >= 0.3) & (t_fast <= 3.0)
            n_read = float(np.median(a_fast[keep] * np.sqrt(t_fast[keep]))) * scale
            b_read = float(a_slow.min()) / 0.664 * scale * (3600.0 if sensor == "gyro" else 1.0)
            b_unit = "deg/h" if sensor == "gyro" else "ug"
            print(f"{preset:8s} {sensor:6s} {'noise density ' + unit + '/rtHz':22s} {density:10.4g} {n_read:10.4g} {n_read / density:6.3f}")
            if instability > 0:
                print(f"{preset:8s} {sensor:6s} {'bias instability ' + b_unit:22s} {instability:10.4g} {b_read:10.4g} {b_read / instability:6.3f}")
            ax = axes[0 if sensor == "gyro" else 1]
            ax.loglog(np.r_[t_fast[t_fast < 1.0], t_slow], np.r_[a_fast[t_fast < 1.0], a_slow] * scale, label=preset)
            if instability > 0:
                floor = 0.664 * instability / (3600.0 if sensor == "gyro" else 1.0)
                ax.axhline(floor, ls=":", lw=0.8, color=ax.lines[-1].get_color())
    for ax, what in zip(axes, ("gyro, deg/s", "accelerometer, ug")):
        ax.set_xlabel("averaging time tau, s")
        ax.set_ylabel(f"Allan deviation, {what}")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(title="dotted: 0.664 x datasheet bias instability")
    fig.suptitle(f"Simulated IMU presets at rest ({args.units} units, 3 axes each)")
    fig.tight_layout()
    with atomic_path(args.out) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    print(f"wrote {args.out}")

    imu, boat = Imu(ImuConfig(preset="mti630")), AtRest()
    start = time.perf_counter()
    for k in range(600):
        imu.sample(boat, imu.times(k * 0.1, (k + 1) * 0.1))
    print(f"100 Hz in 0.1 s batches: {(time.perf_counter() - start) / 60.0 * 1e3:.2f} ms per simulated second")


if __name__ == "__main__":
    main()
