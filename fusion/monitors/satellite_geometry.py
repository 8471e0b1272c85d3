"""How far a range error on each used satellite moves a receiver's horizontal fix, from the azimuths and elevations it
reports (NMEA GSV) and the satellites it used (GSA): the 'slope' of receiver autonomous integrity monitoring.

A least-squares fix x = K y (K = (H^T W H)^-1 H^T W, H's rows [-u_i, clock columns], u_i the unit vector to satellite
i) moves by K[:, i] b for a bias b on satellite i's range; its horizontal part's length is the slope (Misra and Enge,
Global Positioning System, 2nd ed., section 6.2; Brown and Chin 1998, GPS RAIM: calculation of the threshold and
protection radius using chi-square methods, in Global Positioning System vol. V, ION). The weights W are the standard
elevation model a receiver weights its ranges by, sigma^2 = a^2 + (b / sin el)^2 with a = b (RTKLIB's pntpos, Takasu,
RTKLIB ver. 2.4.2 manual, appendix E.6): a low satellite's range is noisier, so it moves the fix less. How a multi-GNSS
receiver handles the systems' time offsets is its own design: one clock, with the broadcast offsets applied (GGTO,
BDT-GPST; the bench's simulated receiver), or one clock per system (RTKLIB's pntpos estimates the inter-system biases),
where a system's only satellite sets its own clock and moves the position not at all (chase_boat at 1613 s: the lone
Galileo satellite, reflected with 60 m of extra path, drew the simulated one-clock receiver's fix 7 m off while the
per-system slope said 0). The monitor cannot tell which it is reading, so each satellite's slope is the larger of the two.
"""

from __future__ import annotations

import numpy as np


def horizontal_slopes(el_deg: np.ndarray, az_deg: np.ndarray, systems: list[str]) -> np.ndarray:
    """Horizontal shift (m) of the elevation-weighted least-squares fix per metre of range bias on each satellite, the
    larger of one receiver clock's and one clock per system's; inf for every satellite when the geometry does not fix a
    position (too few satellites for the position and clocks, a non-finite direction, a singular geometry)."""
    el, az = np.deg2rad(np.asarray(el_deg, dtype=float)), np.deg2rad(np.asarray(az_deg, dtype=float))
    if not (np.isfinite(el).all() and np.isfinite(az).all()) or (np.sin(el) <= 0.0).any():
        return np.full(len(el), np.inf)
    line_of_sight = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1)
    weight = 1.0 / (1.0 + 1.0 / np.sin(el) ** 2)
    one_clock = _slopes(line_of_sight, weight, np.ones((len(el), 1)))
    clocks = sorted(set(systems))
    per_system = _slopes(line_of_sight, weight, np.array([[1.0 if system == key else 0.0 for key in clocks] for system in systems]))
    return np.maximum(one_clock, per_system)


def _slopes(line_of_sight: np.ndarray, weight: np.ndarray, clock: np.ndarray) -> np.ndarray:
    """Slopes for one clock design (clock: the satellites' clock columns), inf where the geometry fixes no position."""
    H = np.hstack([-line_of_sight, clock])
    if len(H) < H.shape[1]:
        return np.full(len(H), np.inf)
    HtW = H.T * weight
    normal = HtW @ H
    if np.linalg.cond(normal) > 1e12:
        return np.full(len(H), np.inf)
    K = np.linalg.solve(normal, HtW)
    return np.hypot(K[0], K[1])
