"""The receiver's velocity from Doppler: what a GNSS receiver reports as speed and course over ground (RMC, VTG).

Receivers do not difference their positions for velocity: each tracked carrier's Doppler shift is the rate of its
range, and a weighted least-squares fit of those range rates over the same geometry as the position (rows [-u_i, 1],
u_i the unit vector to satellite i; the last column the clock's drift) gives the antenna's velocity (Kaplan and
Hegarty, Understanding GPS/GNSS, 3rd ed., section 11.2.2; Misra and Enge, Global Positioning System, 2nd ed.,
section 6.3). The range rates are carrier measurements, so their noise is centimetres a second, not the code's
metres, and the slowly varying code errors that move the position (ionosphere, orbit, the receiver's own filter)
barely change over an epoch: the velocity error is the range-rate noise mapped through the geometry.

A reflected signal (NLOS) is tracked on its reflected path, so its Doppler is the rate of that path: the direct
range's rate plus the rate of the extra path (sim.multipath's image method). Along a quay at a constant distance the
extra path hardly changes and the velocity stays good while the position is metres off; it changes as the
reflecting geometry does. A satellite that changes between direct and reflected between epochs, or to another reflector, has lost lock on the
path it had (a phase jump the tracking loop cannot follow) and is left out of that epoch's velocity; so is a reflected
signal newly tracked, whose path's rate the simulator takes from two epochs (a direct one's is the geometry's).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

MIN_SATELLITES = 4
"""Range rates needed for a velocity and clock drift."""
MAX_PATH_RATE_MPS = 20.0
"""A reflected path changes no faster than twice the antenna's speed (its image moves at most as fast as it does, and
the path's two legs both change); the vessel models sail at most 10 m/s (sim.trajectory). A larger change between
epochs is another reflector: a new path, lock lost as on a switch."""


class DopplerConfig(BaseModel):
    """Range-rate (Doppler) error model of the receiver's velocity."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    range_rate_zenith_mps: float = Field(
        0.04,
        ge=0.0,
        description="Zenith sigma of the white range-rate (Doppler) error per epoch, m/s, grown as 1/sin(el) like the "
        "code's: with the library's four-constellation sky it gives an open-sky horizontal velocity error of 0.042 m/s "
        "at its median (benchmarks/doppler.py, open_river), within the u-blox NEO-M8N and ZED-F9P data sheets' figure "
        "(UBX-15031086, UBX-17051259: velocity accuracy 0.05 m/s, 50 %).",
    )


class DopplerVelocity:
    """The receiver's velocity error per epoch from its tracked satellites' range rates; call at increasing times."""

    def __init__(self, config: DopplerConfig, n_sats: int, rng: np.random.Generator) -> None:
        self.config = config
        self.rng = rng
        self._path = np.full(n_sats, np.nan)  # per satellite at the previous epoch: NaN not tracked, 0 direct, > 0 the reflection's excess
        self._t = -np.inf

    def error(
        self, t: float, view: np.ndarray, tracked: np.ndarray, dirs: np.ndarray, el: np.ndarray, nlos: np.ndarray, extra: np.ndarray, period_s: float
    ) -> np.ndarray | None:
        """ENU velocity error (m/s) of this epoch from the tracked satellites (`tracked`: mask over `view`, the
        constellation indices in view; `dirs` unit vectors to them, `el` elevations, rad; `nlos` received by reflection
        alone, `extra` its excess path, m), or None with fewer than MIN_SATELLITES range rates. A satellite counts when it
        was tracked on the same kind of path at the previous epoch, at most 1.5 `period_s` before: its range rate is then
        known, a reflected one's as its excess path's change over the epoch; a direct one newly tracked counts too."""
        path = np.where(nlos, extra, 0.0)
        before = self._path[view]
        dt, self._t = t - self._t, t
        self._path = np.full(len(self._path), np.nan)
        self._path[view[tracked]] = path[tracked]
        draws = self.rng.standard_normal(len(view))  # one draw per satellite in view: the stream does not depend on the sky's blockage
        if dt > 1.5 * period_s:  # after a gap no carrier was tracked at the last epoch
            before = np.full(len(view), np.nan)
        path_rate = (path - np.nan_to_num(before)) / dt
        continued = np.isfinite(before) & ((before > 0.0) == nlos) & (np.abs(path_rate) <= MAX_PATH_RATE_MPS)
        acquired = np.isnan(before) & ~nlos  # a direct signal newly tracked: its range rate is the geometry's, known
        path_rate[acquired] = 0.0
        rates = tracked & (continued | acquired)
        if rates.sum() < MIN_SATELLITES:
            return None
        sin_el = np.sin(el[rates])
        residual = self.config.range_rate_zenith_mps / sin_el * draws[rates] + path_rate[rates]
        g = np.hstack([-dirs[rates], np.ones((int(rates.sum()), 1))])
        gw = g.T * sin_el**2  # weights 1 / sigma^2, sigma growing as 1 / sin(el); their scale cancels
        return (np.linalg.solve(gw @ g, gw @ residual))[:3]
