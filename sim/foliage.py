"""Laser returns from tree crowns as from a turbid medium: each ray's echo comes from a leaf at a random depth in the
crown, drawn afresh for every ray of every revolution.

The world's crowns are filled with leaf clusters a metre or more across (worlds.vegetation) so that their transmission
is right at a tractable triangle count. A laser, though, is stopped by single leaves (5-10 cm) much smaller than the
spacing of the HDL-32E's rays (0.17 deg azimuth step: 0.23 m at 80 m) and its footprint (3.3 mrad: 0.26 m at 80 m), and
leaves flutter: two revolutions' rays into the same crown meet unrelated leaves, so foliage returns do not repeat from
scan to scan the way a facet's would. Where along the ray the echo comes from follows the gap probability of a
turbid medium (Beer-Lambert: the ray is still travelling after s metres of crown with probability exp(-k s), k the
crown's extinction, worlds.crowns; MacArthur & Horn 1969, "Foliage profile by vertical measurements", Ecology 50;
Ni-Meister et al. 2001, "Modeling lidar waveforms in heterogeneous and discrete canopies", IEEE TGRS 39). Whether the
ray stops in the crown at all is left to the facets, which give that probability on average.
"""

from __future__ import annotations

import numpy as np

from worlds.crowns import Crowns


def crown_echo_ranges(crowns: Crowns, origins: np.ndarray, directions: np.ndarray, t_hit: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """New ranges (M,) of rays (origins, unit directions (M, 3)) that hit foliage facets at t_hit (M,): a depth into the
    crown holding the hit, drawn from the exponential of its extinction truncated to the ray's chord through it (the
    ray stopped somewhere in that chord). A hit no crown holds keeps its range."""
    t_hit = np.asarray(t_hit, dtype=float)
    out = t_hit.copy()
    crown, entry, exit_ = crowns.chord_at(np.asarray(origins, dtype=float), np.asarray(directions, dtype=float), t_hit)
    inside = crown >= 0
    u = rng.random(len(t_hit))[inside]
    k = crowns.extinction_per_m[crown[inside]]
    chord = np.maximum(exit_[inside] - entry[inside], 0.0)
    depth = -np.log1p(-u * -np.expm1(-k * chord)) / k  # inverse CDF of Exp(k) on [0, chord]
    out[inside] = entry[inside] + depth
    return out
