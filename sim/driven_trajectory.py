"""A trajectory driven by thruster commands: the 3-DoF WAM-V model integrated as commands arrive.

It answers the questions the LiDAR and the receiver ask of `sim.Trajectory` (pose at any time,
vectorised, mount, hull), for any time from the start up to how far it has been driven, so the
HDL-32E's motion distortion and the receiver's antenna position work unchanged. Heave, roll and
pitch come from the same wave model as the open-loop trajectory; the plane motion from the model.
A bounded history is kept (memory stays flat in run length).
"""

from __future__ import annotations

import numpy as np

from riverbench.rng import stream
from sim.dynamics import Manoeuvring, WamvDynamics
from sim.plane_motion import PlaneMotion
from sim.trajectory import TrajectoryConfig, VesselPoses, mount_matrix, wave_poses

STEP_S = 0.01
"""Integration step (RK4); the pose between two steps is interpolated linearly (error < 0.1 mm at 2 m/s)."""
HISTORY_S = 120.0
"""How far back poses stay available (a chase boat's lag, a report's look back)."""


class DrivenTrajectory(VesselPoses):
    """World<-base_link poses of a vessel that moves as `drive(commands, until)` tells it.

    start: (x, y, yaw, u) at time t0 (ENU metres, rad from east, surge m/s). `config` gives the
    mount, hull, sea state and the wave seed as for sim.Trajectory; `dynamics` the WAM-V model.
    """

    def __init__(
        self,
        config: TrajectoryConfig,
        dynamics: WamvDynamics,
        start: tuple[float, float, float, float],
        t0: float = 0.0,
        current_enu: tuple[float, float] = (0.0, 0.0),
    ):
        self.config = config
        self.model = Manoeuvring(dynamics, current_enu)
        rng = stream(config.seed, "sim.trajectory")
        rng.uniform(0.0, 2.0 * np.pi)  # the open-loop trajectory's speed phase: same waves for the same seed
        self.waves = config.wave_motion(rng)
        self.mount = mount_matrix(config)
        x, y, yaw, u = start
        self._t = np.array([float(t0)])
        self._state = np.array([[x, y, yaw, u, 0.0, 0.0]])
        self.t0 = float(t0)

    @property
    def duration(self) -> float:
        """The latest time the vessel has been driven to (poses exist up to here)."""
        return float(self._t[-1])

    @property
    def state(self) -> np.ndarray:
        """(x, y, yaw, u, v, r) now, at `duration`."""
        return self._state[-1].copy()

    def drive(self, commands: tuple[float, float], until: float) -> None:
        """Hold the (left, right) thruster commands in [-1, 1] from now until time `until`."""
        cmd = np.asarray(commands, dtype=float)
        if cmd.shape != (2,) or not np.isfinite(cmd).all():
            raise ValueError(f"driven trajectory: commands must be two finite numbers in [-1, 1], got {commands!r}")
        n = int(np.ceil((until - self.duration) / STEP_S - 1e-9))
        if n <= 0:
            return
        dt = (until - self.duration) / n
        states = np.empty((n, 6))
        state = self._state[-1]
        for i in range(n):
            state = self.model.step(state, cmd, dt)
            states[i] = state
        self._t = np.r_[self._t, self.duration + dt * np.arange(1, n + 1)]
        self._state = np.vstack([self._state, states])
        keep = self._t >= self._t[-1] - HISTORY_S
        if not keep[0]:
            self._t, self._state = self._t[keep], self._state[keep]

    def poses(self, ts: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world<-base_link at times ts within the kept history, vectorised."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        if not np.isfinite(ts).all():
            raise ValueError("driven trajectory: time is NaN or infinite")
        if ts.min() < self._t[0] - 1e-9 or ts.max() > self._t[-1] + 1e-9:
            raise ValueError(f"driven trajectory: time {ts.min():.3f}..{ts.max():.3f} s outside the driven {self._t[0]:.3f}..{self._t[-1]:.3f} s")
        xy = np.stack([np.interp(ts, self._t, self._state[:, k]) for k in (0, 1)], axis=-1)
        return wave_poses(ts, xy, np.interp(ts, self._t, self._state[:, 2]), self.waves)

    def plane_motion(self, ts: np.ndarray) -> PlaneMotion:
        """Position, yaw, world velocity and acceleration and yaw rate at ts from the integrated state (body
        velocities over ground, yaw rate; their rates of change by differences of the RK4 steps)."""
        poses = self.poses(ts)  # checks the times
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        state = {k: np.interp(ts, self._t, self._state[:, k]) for k in range(6)}
        rates = np.gradient(self._state[:, 3:6], self._t, axis=0) if len(self._t) > 1 else np.zeros((1, 3))
        u_dot, v_dot = (np.interp(ts, self._t, rates[:, k]) for k in (0, 1))
        yaw, u, v, r = state[2], state[3], state[4], state[5]
        c, s = np.cos(yaw), np.sin(yaw)
        body_accel = (u_dot - r * v, v_dot + r * u)
        velocity = np.stack([c * u - s * v, s * u + c * v], axis=-1)
        acceleration = np.stack([c * body_accel[0] - s * body_accel[1], s * body_accel[0] + c * body_accel[1]], axis=-1)
        return PlaneMotion(poses[:, :2, 3], yaw, velocity, acceleration, r)

    def speed(self, t: float) -> float:
        """Speed over ground (m/s) at the driven time nearest t (body velocities are over ground)."""
        i = min(int(np.searchsorted(self._t, t)), len(self._t) - 1)
        return float(np.hypot(self._state[i, 3], self._state[i, 4]))
