"""Top view of an episode for render_mode="rgb_array": the world's structures around the vessel, the route,
the true hull and track, the estimator's pose, the latest fix and the current scan."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PolyCollection

VIEW_M = 80.0
"""Side of the square view centred on the vessel."""
PIXELS = 480


class TopView:
    """Draws frames of one world; the structures' triangles (everything but the water) are projected once."""

    def __init__(self, world):
        solid = [p for p in world.parts if not p.material.water]
        tris = [np.asarray(p.mesh.triangles)[:, :, :2] for p in solid]
        kinds = [np.full(len(p.mesh.faces), i) for i, p in enumerate(solid)]
        self.triangles = np.concatenate(tris) if tris else np.zeros((0, 3, 2))
        self.part_of = np.concatenate(kinds) if kinds else np.zeros(0, int)
        self.lo, self.hi = self.triangles.min(axis=1), self.triangles.max(axis=1)
        palette, kinds = plt.get_cmap("tab20"), sorted({p.kind for p in solid})
        # overhead parts (decks, girders: nothing below 2 m) are drawn faint so that what the hull can hit shows through
        self.colours = (
            np.array([(*palette(kinds.index(p.kind) % 20)[:3], 0.15 if p.mesh.bounds[0, 2] > 2.0 else 0.6) for p in solid])
            if solid
            else np.zeros((0, 4))
        )
        self.route = world.route
        self.fig, self.ax = plt.subplots(figsize=(PIXELS / 100, PIXELS / 100), dpi=100)

    def draw(self, trajectory, t: float, estimate: np.ndarray, fix, scan, log) -> np.ndarray:
        """(PIXELS, PIXELS, 3) uint8 frame at time t."""
        ax = self.ax
        ax.clear()
        truth = trajectory.pose(t)
        cx, cy = truth[0, 3], truth[1, 3]
        half = VIEW_M / 2
        centre = np.array([cx, cy])
        near = np.flatnonzero(np.all((self.hi > centre - half) & (self.lo < centre + half), axis=1))
        ax.add_collection(PolyCollection(self.triangles[near], facecolors=self.colours[self.part_of[near]], edgecolors="none"))
        ax.plot(self.route.xy[:, 0], self.route.xy[:, 1], "--", color="0.5", lw=0.8, label="route")
        track = np.array([(r[1], r[2]) for r in log.rows[-600:]])
        if len(track):
            ax.plot(track[:, 0], track[:, 1], color="tab:blue", lw=1.0)
        if scan is not None and len(scan.points):
            pts = np.stack([scan.points["x"], scan.points["y"], scan.points["z"], np.ones(len(scan.points))], axis=1)
            world_pts = (trajectory.lidar_pose(scan.stamp) @ pts.T).T
            ax.scatter(world_pts[:, 0], world_pts[:, 1], s=1.5, c="k", lw=0, label=f"scan ({len(pts)} pts)")
        _hull(ax, truth, "tab:blue", "truth")
        if np.isfinite(estimate).all():
            _hull(ax, estimate, "tab:red", "estimate")
        if fix is not None and fix.quality:
            ax.plot(fix.enu[0], fix.enu[1], "o", ms=5, mfc="none", mec="tab:orange", label=f"GPS fix (q{fix.quality})")
        clearance = log.rows[-1][6] if log.rows else math.nan
        ax.set_title(f"t={t:.1f} s  clearance {clearance:.1f} m  {log.outcome if log.outcome != 'interrupted' else ''}", fontsize=8)
        ax.set_xlim(cx - half, cx + half)
        ax.set_ylim(cy - half, cy + half)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=6)
        ax.legend(loc="lower left", fontsize=6, markerscale=3)
        self.fig.tight_layout()
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        plt.close(self.fig)


def _hull(ax, pose: np.ndarray, colour: str, label: str, length: float = 4.9, beam: float = 2.4) -> None:
    """The WAM-V footprint at a pose, with a bow mark."""
    corners = np.array(
        [
            [length / 2, beam / 2],
            [-length / 2, beam / 2],
            [-length / 2, -beam / 2],
            [length / 2, -beam / 2],
            [length / 2 + 1.0, 0.0],
            [length / 2, beam / 2],
        ]
    )
    xy = corners @ pose[:2, :2].T + pose[:2, 3]
    ax.fill(xy[:, 0], xy[:, 1], facecolor="none", edgecolor=colour, lw=1.5, label=label)
