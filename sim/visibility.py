"""Signal paths by ray casting against the world mesh: direct line of sight and reflected legs.

All rays of one epoch go to Open3D's RaycastingScene in one batch: two vertical probes that detect
an antenna inside a solid, one ray per satellite from the antenna (line of sight when it hits
nothing), and two legs per candidate reflection (facade -> satellite must hit nothing; facade ->
antenna must hit nothing before the antenna).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from sim.multipath import Reflections

START_OFFSET_M = 1e-3
"""Rays start this far from their origin surface (facade) or antenna to avoid self hits."""


@dataclass(frozen=True)
class SignalPaths:
    """Outcome of one epoch's ray cast.

    los: (M,) direct path clear per satellite; reflection_clear: (K,) both legs of each candidate
    reflection clear; inside_solid: the antenna sits inside a closed mesh part (bad input).
    """

    los: np.ndarray
    reflection_clear: np.ndarray
    inside_solid: bool


def trace(scene: o3d.t.geometry.RaycastingScene, antenna: np.ndarray, directions: np.ndarray,
          reflections: Reflections) -> SignalPaths:
    """Cast the probes, line-of-sight rays and reflection legs of one epoch in one batch."""
    m, k = len(directions), len(reflections)
    rays = np.empty((2 + m + 2 * k, 6), dtype=np.float32)
    rays[:2, :3] = antenna
    rays[:2, 3:] = ((0.0, 0.0, 1.0), (0.0, 0.0, -1.0))
    rays[2:2 + m, :3] = antenna + START_OFFSET_M * directions
    rays[2:2 + m, 3:] = directions
    leg_length = np.zeros(0)
    if k:
        start = reflections.point + START_OFFSET_M * reflections.normal
        up = slice(2 + m, 2 + m + k)
        down = slice(2 + m + k, None)
        rays[up, :3] = start
        rays[up, 3:] = directions[reflections.sat]
        to_antenna = antenna - start
        leg_length = np.linalg.norm(to_antenna, axis=1)
        rays[down, :3] = start
        rays[down, 3:] = to_antenna / leg_length[:, None]
    hits = scene.cast_rays(o3d.core.Tensor(rays))
    t_hit = hits["t_hit"].numpy()
    probe_normals = hits["primitive_normals"].numpy()[:2]
    # Inside a closed, outward-facing solid both vertical probes first meet a face from behind.
    inside = bool(np.all(np.isfinite(t_hit[:2])) and np.all(np.einsum("ij,ij->i", probe_normals, rays[:2, 3:]) > 0))
    los = np.isinf(t_hit[2:2 + m])
    clear = np.isinf(t_hit[2 + m:2 + m + k]) & (t_hit[2 + m + k:] >= leg_length - START_OFFSET_M)
    return SignalPaths(los=los, reflection_clear=clear, inside_solid=inside)
