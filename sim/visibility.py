"""Signal paths by ray casting against the world mesh: direct line of sight and reflected legs.

All rays of one epoch go to Open3D's RaycastingScene in one batch: five probes (up and the four
horizontal axes) that detect an antenna inside a solid, one ray per satellite from the antenna (line of sight when it hits
nothing), and two legs per candidate reflection (facade -> satellite must hit nothing; facade ->
antenna must hit nothing before the antenna).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import open3d as o3d

from sim.multipath import Reflections

START_OFFSET_M = 1e-3
"""Rays start this far from their origin surface (facade) or antenna to avoid self hits."""
PROBES = np.array([[0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=np.float32)
"""Inside a closed, outward-facing solid every probe first meets a face from behind. (Down is not a
probe: parts often overlap the water surface, whose top face then lies inside them.)"""


@dataclass(frozen=True)
class SignalPaths:
    """Outcome of one epoch's ray cast.

    los: (M,) direct path clear per satellite; reflection_clear: (K,) both legs of each candidate
    reflection clear; inside_solid: the antenna sits inside a closed mesh part (bad input).
    """

    los: np.ndarray
    reflection_clear: np.ndarray
    inside_solid: bool


def trace(
    scene: o3d.t.geometry.RaycastingScene,
    antenna: np.ndarray,
    directions: np.ndarray,
    reflections: Reflections,
    movers: Callable[[np.ndarray], np.ndarray] | None = None,
) -> SignalPaths:
    """Cast the probes, line-of-sight rays and reflection legs of one epoch in one batch; `movers`, if given,
    maps world rays (N, 6) to the distance to the nearest moving body (inf: none), which blocks them too."""
    m, k = len(directions), len(reflections)
    p = len(PROBES)
    rays = np.empty((p + m + 2 * k, 6), dtype=np.float32)
    rays[:p, :3] = antenna
    rays[:p, 3:] = PROBES
    rays[p : p + m, :3] = antenna + START_OFFSET_M * directions
    rays[p : p + m, 3:] = directions
    leg_length = np.zeros(0)
    if k:
        start = reflections.point + START_OFFSET_M * reflections.normal
        up = slice(p + m, p + m + k)
        down = slice(p + m + k, None)
        rays[up, :3] = start
        rays[up, 3:] = directions[reflections.sat]
        to_antenna = antenna - start
        leg_length = np.linalg.norm(to_antenna, axis=1)
        rays[down, :3] = start
        rays[down, 3:] = to_antenna / leg_length[:, None]
    hits = scene.cast_rays(o3d.core.Tensor(rays))
    t_hit = hits["t_hit"].numpy()
    if movers is not None:
        t_hit[p:] = np.minimum(t_hit[p:], movers(rays[p:]))
    inside = bool(np.isfinite(t_hit[:p]).all() and ((hits["primitive_normals"].numpy()[:p] * PROBES).sum(1) > 0).all())
    los = np.isinf(t_hit[p : p + m])
    clear = np.isinf(t_hit[p + m : p + m + k]) & (t_hit[p + m + k :] >= leg_length - START_OFFSET_M)
    return SignalPaths(los=los, reflection_clear=clear, inside_solid=inside)
