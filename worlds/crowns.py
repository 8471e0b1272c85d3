"""Tree crown envelopes: upright spheroids the foliage facets fill, and path lengths through them.

The LiDAR sees a crown as its porous facets (worlds.vegetation); a GNSS signal is not blocked by it
but loses C/N0 in proportion to the length of its path inside the envelope (sim.gnss). Crowns may
overlap: a path through two overlapping crowns counts the shared part twice, as their facets are
there twice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Crowns:
    """N crowns: centre (N, 3) ENU m; radius (N, 2) horizontal and vertical semi-axes, m."""

    centre: np.ndarray
    radius: np.ndarray

    def __post_init__(self) -> None:
        if self.centre.shape != (len(self), 3) or self.radius.shape != (len(self), 2) or (self.radius <= 0).any():
            raise ValueError(f"crowns: need centre (N, 3) and positive radius (N, 2), got {self.centre.shape}, {self.radius.shape}")

    def __len__(self) -> int:
        return len(self.centre)

    @classmethod
    def empty(cls) -> Crowns:
        return cls(np.zeros((0, 3)), np.zeros((0, 2)))

    @classmethod
    def concatenate(cls, crowns: list[Crowns]) -> Crowns:
        return cls(np.concatenate([c.centre for c in crowns] + [np.zeros((0, 3))]), np.concatenate([c.radius for c in crowns] + [np.zeros((0, 2))]))

    def path_length(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Total length (m) inside crowns of the rays from `origin` (3,) along unit `directions` (M, 3).

        Each spheroid becomes the unit sphere by scaling its axes; a ray o + t d then solves
        |o' + t d'|^2 = 1, and its chord is the part of [t1, t2] with t >= 0 (t stays in metres).
        """
        directions = np.asarray(directions, dtype=float).reshape(-1, 3)
        if not len(self) or not len(directions):
            return np.zeros(len(directions))
        scale = 1.0 / np.c_[self.radius[:, :1], self.radius]  # (N, 3)
        o = (np.asarray(origin, dtype=float) - self.centre) * scale  # (N, 3)
        d = directions[:, None, :] * scale[None, :, :]  # (M, N, 3)
        a = np.einsum("mnk,mnk->mn", d, d)
        b = np.einsum("mnk,nk->mn", d, o)
        c = np.einsum("nk,nk->n", o, o) - 1.0
        disc = b * b - a * c[None, :]
        root = np.sqrt(np.maximum(disc, 0.0))
        t1, t2 = (-b - root) / a, (-b + root) / a
        chord = np.where(disc > 0, np.maximum(t2 - np.maximum(t1, 0.0), 0.0), 0.0)
        return chord.sum(axis=1)
