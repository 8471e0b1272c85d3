"""3-DoF manoeuvring model (surge, sway, yaw) of a WAM-V 16 driven by two fixed stern thrusters.

Fossen's rigid-body + added-mass model with linear and quadratic damping, in a uniform water
current: (M_RB + M_A) dnu/dt + (C_RB + C_A)(nu_r) nu_r + D(nu_r) nu_r = tau(commands), with nu_r
the velocity through the water. Thruster commands are in [-1, 1] as the field's marine simulators
take them (VRX: 1 is full ahead, -1 full astern, a linear map to force).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field


class WamvDynamics(BaseModel):
    """WAM-V 16 parameters. Mass, inertia, damping and thrusters: the VRX model (Bingham et al., "Toward
    Maritime Robotic Simulation in Gazebo", OCEANS 2019), identified on a real WAM-V. VRX sets the
    added mass to zero. Here it is small and explicit: surge 5% of the mass (Fossen's slender-body
    rule of thumb), sway 10%, yaw 10% of the inertia (two shallow inflatable demihulls, ~0.12 m
    draft, displace little water). Sway added mass above ~23 kg would, with VRX's sway damping,
    make the straight course unstable through the Munk moment (Yv Nr < m11 (m22 - m11) U^2 at full
    speed), which a real WAM-V on its skegs is not; tests check the straight course is stable."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    mass_kg: float = Field(180.0, gt=0, description="rigid-body mass (VRX wamv_base)")
    inertia_z_kgm2: float = Field(446.0, gt=0, description="yaw moment of inertia (VRX wamv_base)")
    added_mass_surge_kg: float = Field(9.0, ge=0, description="-X_udot: 5% of the mass")
    added_mass_sway_kg: float = Field(18.0, ge=0, description="-Y_vdot: 10% of the mass")
    added_inertia_yaw_kgm2: float = Field(44.6, ge=0, description="-N_rdot: 10% of the yaw inertia")
    x_u: float = Field(51.3, ge=0, description="linear surge damping, N s/m (VRX xU)")
    x_uu: float = Field(72.4, ge=0, description="quadratic surge damping, N s^2/m^2 (VRX xUU)")
    y_v: float = Field(40.0, ge=0, description="linear sway damping, N s/m (VRX yV)")
    y_vv: float = Field(0.0, ge=0, description="quadratic sway damping (VRX yVV)")
    n_r: float = Field(400.0, ge=0, description="linear yaw damping, N m s (VRX nR)")
    n_rr: float = Field(0.0, ge=0, description="quadratic yaw damping (VRX nRR)")
    max_thrust_fwd_n: float = Field(250.0, gt=0, description="one thruster's force at command +1 (VRX maxForceFwd)")
    max_thrust_rev_n: float = Field(100.0, gt=0, description="one thruster's force at command -1 (VRX maxForceRev)")
    thruster_x_m: float = Field(-2.373776, description="thrusters' position aft of base_link (VRX)")
    thruster_y_m: float = Field(1.027135, gt=0, description="each thruster's distance from the centreline (VRX)")

    def thrust(self, commands: np.ndarray) -> np.ndarray:
        """Forces (N) of the (left, right) thrusters for commands clipped to [-1, 1]."""
        c = np.clip(np.asarray(commands, dtype=float), -1.0, 1.0)
        return np.where(c >= 0.0, c * self.max_thrust_fwd_n, c * self.max_thrust_rev_n)

    def steady_surge_mps(self, force_n: float) -> float:
        """Surge speed through the water where damping balances a total forward force (straight run)."""
        return float((-self.x_u + np.sqrt(self.x_u**2 + 4.0 * self.x_uu * force_n)) / (2.0 * self.x_uu)) if self.x_uu else force_n / self.x_u

    def cruise_command(self, speed_mps: float) -> float:
        """The equal command on both thrusters that holds `speed_mps` on a straight run in still water."""
        force = self.x_u * speed_mps + self.x_uu * speed_mps * abs(speed_mps)
        return float(np.clip(force / (2.0 * self.max_thrust_fwd_n), -1.0, 1.0))


class Manoeuvring:
    """Integrates the 3-DoF model. State: (x, y, yaw, u, v, r) in the world ENU frame and body velocities."""

    def __init__(self, params: WamvDynamics, current_enu: tuple[float, float] = (0.0, 0.0)):
        self.params = params
        self._m11 = params.mass_kg + params.added_mass_surge_kg
        self._m22 = params.mass_kg + params.added_mass_sway_kg
        self._m33 = params.inertia_z_kgm2 + params.added_inertia_yaw_kgm2
        self._current = np.asarray(current_enu, dtype=float)

    def derivative(self, state: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """d(state)/dt for thruster forces (left, right), N."""
        p = self.params
        _, _, yaw, u, v, r = state
        c, s = np.cos(yaw), np.sin(yaw)
        # the current in the body frame; it is uniform and steady, so d(nu_c)/dt = -S(r) nu_c
        uc, vc = c * self._current[0] + s * self._current[1], -s * self._current[0] + c * self._current[1]
        ur, vr = u - uc, v - vc
        surge = forces[0] + forces[1]
        yaw_moment = p.thruster_y_m * (forces[1] - forces[0])
        m11, m22, m33 = self._m11, self._m22, self._m33
        # in a uniform, steady current the whole model holds in nu_r (Fossen 2011, Property 10.1)
        du_r = (surge + m22 * vr * r - (p.x_u + p.x_uu * abs(ur)) * ur) / m11
        dv_r = (-m11 * ur * r - (p.y_v + p.y_vv * abs(vr)) * vr) / m22
        dr = (yaw_moment - (m22 - m11) * ur * vr - (p.n_r + p.n_rr * abs(r)) * r) / m33
        # body accelerations of nu = nu_r + nu_c, with the rotating frame's effect on the current
        du = du_r + r * vc
        dv = dv_r - r * uc
        return np.array([c * u - s * v, s * u + c * v, r, du, dv, dr])

    def step(self, state: np.ndarray, commands: np.ndarray, dt: float) -> np.ndarray:
        """One classical Runge-Kutta step of dt seconds with the commands held."""
        f = self.params.thrust(commands)
        k1 = self.derivative(state, f)
        k2 = self.derivative(state + 0.5 * dt * k1, f)
        k3 = self.derivative(state + 0.5 * dt * k2, f)
        k4 = self.derivative(state + dt * k3, f)
        return state + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
