"""Tree crown envelopes: upright spheroids the foliage facets fill, and path lengths through them.

The LiDAR sees a crown as its porous facets (worlds.vegetation); a GNSS signal is not blocked by it
but loses C/N0 in proportion to the length of its path inside the envelope (sim.gnss). Crowns may
overlap: a path through two overlapping crowns counts the shared part twice, as their facets are
there twice.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class Crowns:
    """N crowns: centre (N, 3) ENU m; radius (N, 2) horizontal and vertical semi-axes, m; extinction (N,) 1/m: the
    rate at which a laser crossing the crown meets leaves (leaf area density x the mean projection of a randomly
    oriented leaf, 0.5; Ross 1981, The Radiation Regime and Architecture of Plant Stands), so it passes a length L
    with probability exp(-extinction * L) (Beer-Lambert, as the facets of worlds.vegetation give on average)."""

    centre: np.ndarray
    radius: np.ndarray
    extinction_per_m: np.ndarray

    def __post_init__(self) -> None:
        n = len(self)
        if self.centre.shape != (n, 3) or self.radius.shape != (n, 2) or (self.radius <= 0).any():
            raise ValueError(f"crowns: need centre (N, 3) and positive radius (N, 2), got {self.centre.shape}, {self.radius.shape}")
        if self.extinction_per_m.shape != (n,) or not (self.extinction_per_m > 0).all():
            raise ValueError(f"crowns: need a positive extinction per crown ({n},), got {self.extinction_per_m.shape}")

    def __len__(self) -> int:
        return len(self.centre)

    @classmethod
    def empty(cls) -> Crowns:
        return cls(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0))

    @classmethod
    def concatenate(cls, crowns: list[Crowns]) -> Crowns:
        return cls(
            np.concatenate([c.centre for c in crowns] + [np.zeros((0, 3))]),
            np.concatenate([c.radius for c in crowns] + [np.zeros((0, 2))]),
            np.concatenate([c.extinction_per_m for c in crowns] + [np.zeros(0)]),
        )

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
        disc, t1, t2 = _roots(a, b, c[None, :])
        chord = np.where(disc > 0, np.maximum(t2 - np.maximum(t1, 0.0), 0.0), 0.0)
        return chord.sum(axis=1)

    @cached_property
    def _index(self) -> cKDTree:
        """Search tree of the crown centres (built on first use; a world's crowns never change)."""
        return cKDTree(self.centre)

    def chord_at(self, origins: np.ndarray, directions: np.ndarray, t: np.ndarray, candidates: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For rays o + s d (origins, unit directions (M, 3)) that hit foliage at range t (M,): the crown they hit
        (index, -1 where no crown's chord holds t, within 1 cm) and the chord through it, (entry >= 0, exit) in metres
        along the ray. Of the `candidates` crowns whose centres are nearest the hit, the nearest that holds it."""
        m = len(t)
        crown, entry, exit_ = np.full(m, -1), np.zeros(m), np.zeros(m)
        if not len(self) or not m:
            return crown, entry, exit_
        hit = origins + directions * t[:, None]
        k = min(candidates, len(self))
        _, near = self._index.query(hit, k=k, distance_upper_bound=float(self.radius.max()) + 0.01)
        near = near.reshape(m, k)
        real = near < len(self)
        idx = np.where(real, near, 0)
        scale = 1.0 / np.concatenate([self.radius[idx][..., :1], self.radius[idx]], axis=-1)  # (M, k, 3)
        o = (origins[:, None, :] - self.centre[idx]) * scale
        d = directions[:, None, :] * scale
        a = np.einsum("mkj,mkj->mk", d, d)
        b = np.einsum("mkj,mkj->mk", d, o)
        disc, s1, s2 = _roots(a, b, np.einsum("mkj,mkj->mk", o, o) - 1.0)
        holds = real & (disc > 0) & (s1 - 0.01 <= t[:, None]) & (t[:, None] <= s2 + 0.01)
        found = holds.any(axis=1)
        first = np.argmax(holds, axis=1)
        rows = np.flatnonzero(found)
        crown[rows] = idx[rows, first[rows]]
        entry[rows] = np.maximum(s1[rows, first[rows]], 0.0)
        exit_[rows] = s2[rows, first[rows]]
        return crown, entry, exit_


def _roots(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(discriminant, smaller root, larger root) of a t^2 + 2 b t + c = 0: where a ray meets a crown scaled to the unit
    sphere (no crossing where the discriminant is not positive)."""
    disc = b * b - a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    return disc, (-b - root) / a, (-b + root) / a
