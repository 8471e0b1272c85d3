"""The laser beam's footprint: where it straddles a depth edge, the HDL-32E reports a mixed pixel.

A beam of horizontal divergence theta lights a strip r * theta wide. Where that strip falls partly
on a near surface and partly on a far one (a pier's side, a tree trunk, a building corner, a hull),
the two echoes merge in the receiver and the sensor reports one range between the two surfaces,
weighted by the power each part returns (the mixed-pixel effect: Hebert & Krotkov 1992, "3D
measurements from imaging laser radars", Image Vision Comput. 10(3); Tuley et al. 2005, "Analysis and
removal of artifacts in 3-D LADAR data", ICRA). Where it falls partly on nothing (the sky) or on
water (specular: no echo comes back), the return keeps the lit surface's range but loses power, so
a silhouette's edge is detected less often.

Only rays next to a depth edge need the footprint: with the HDL-32E's 3.3 mrad horizontal divergence
over its 2.9 mrad azimuth step (10 Hz), an edge inside a beam's strip lies between that beam and one
of its two azimuth neighbours, so comparing a ray's range with its neighbours' finds every such ray. The vertical
divergence (0.7 mrad) is 33 times smaller than the 23 mrad between lasers and is not modelled.
"""

from __future__ import annotations

import numpy as np


def edge_sides(t_hit: np.ndarray, valid: np.ndarray, gap_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(n_firings, 32) each: rays at a depth edge shared with the previous firing's ray of their laser, and
    with the next one's. A ray is at a depth edge when it returns and a neighbour does not (or the reverse),
    or when its range kinks: the second difference over the ray and its two azimuth neighbours exceeds gap_m.
    A smooth surface, even at grazing incidence, has a range that changes almost linearly from ray to ray,
    so it is no edge; a step of J metres gives second differences of +-J on both rays beside it. The edge
    lies on the side(s) where validity changes or the range steps by more than gap_m / 2."""
    r = np.where(valid, t_hit, 0.0)
    lit, prev, nxt = valid[1:-1], valid[:-2], valid[2:]
    kink = lit & prev & nxt & (np.abs(r[:-2] - 2.0 * r[1:-1] + r[2:]) > gap_m)
    step_prev = (lit != prev) | (kink & (np.abs(r[1:-1] - r[:-2]) > 0.5 * gap_m))
    step_next = (lit != nxt) | (kink & (np.abs(r[2:] - r[1:-1]) > 0.5 * gap_m))
    before, after = np.zeros_like(valid), np.zeros_like(valid)
    before[1:-1], after[1:-1] = step_prev, step_next
    return before, after


def edge_rays(t_hit: np.ndarray, valid: np.ndarray, gap_m: float) -> np.ndarray:
    """(n_firings, 32) True for rays at a depth edge on either side (see `edge_sides`)."""
    before, after = edge_sides(t_hit, valid, gap_m)
    return before | after


def footprint_offsets(divergence_rad: float, samples: int) -> np.ndarray:
    """Azimuth offsets (rad) of the footprint's samples other than the beam's centre: the centres of `samples`
    equal slices of the strip, the middle one (offset 0) being the beam's own ray. The head spins clockwise,
    so a positive offset looks towards the previous firing."""
    k = np.arange(samples) - (samples - 1) / 2
    offsets = k * divergence_rad / samples
    return offsets[offsets != 0.0]


def mix(t: np.ndarray, power: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mixed pixels from the footprint's samples, (m, K) each: range t (m) and returned power
    (reflectivity * cos(incidence) / r^2, 0 where a sample returns nothing).

    Returns the mean power over the footprint (what the detector sees), the power-weighted mean
    range (nan where no sample returns), and the index of the strongest sample (whose surface labels
    the point)."""
    total = power.sum(axis=1)
    mean_power = total / power.shape[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        weighted = np.where(power > 0, power * t, 0.0).sum(axis=1) / total
    return mean_power, weighted, np.argmax(power, axis=1)
