"""The de-skew/register rounds of the matchers that de-skew scans themselves (gicp, pcl6d).

A scan is de-skewed with the constant-velocity prior, registered, and de-skewed again with the twist
of the new estimate while that twist still changes (`twist_changed`), at most `rounds` times.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, TypeVar

import numpy as np

from matcher.cloud import Cloud
from matcher.motion import se3_log, twist_changed


class Prepared(Protocol):
    """A scan made ready to match: the cloud it came from and the twist it was de-skewed with (None: as it is)."""

    cloud: Cloud
    twist: np.ndarray | None


P = TypeVar("P", bound=Prepared)
X = TypeVar("X")


def deskew_rounds(
    cloud: Cloud,
    ref: P,
    twist: np.ndarray | None,
    init: np.ndarray | None,
    dt: float,
    rounds: int,
    prepare: Callable[[Cloud, np.ndarray | None], P],
    align: Callable[[P, P, np.ndarray | None], tuple[np.ndarray, X] | None],
    prepare_ref: Callable[[Cloud, np.ndarray | None], P] | None = None,
) -> tuple[P, P, tuple[np.ndarray, X] | None]:
    """Register `cloud` (dt s after the reference `ref`) in up to `rounds` de-skew rounds (at least one).

    Each round prepares `cloud` de-skewed with the current `twist` (per second), aligns it with
    `align(cur, ref, T)` from the previous round's T (`init` in the first) to (T, whatever else the
    matcher needs) and takes the twist se3_log(T) / dt of the new estimate; a reference that was
    never de-skewed (its twist is None: the first scan) is prepared again with it (`prepare_ref`,
    `prepare` by default). The rounds stop when the twist no longer changes. `align` returns None
    when cur or ref has too few points: the rounds end there.

    Returns (the reference, the last prepared scan, the last round's (T, ...) or None when it had too few points).
    """
    if rounds < 1:
        raise ValueError(f"rounds must be at least 1, got {rounds}")
    T = init
    done = 0
    while True:
        cur = prepare(cloud, twist)
        aligned = align(cur, ref, T)
        if aligned is None:
            return ref, cur, None
        T = aligned[0]
        done += 1
        new_twist = se3_log(T) / dt
        if ref.twist is None:  # the first reference was never de-skewed: use this estimate
            ref = (prepare_ref or prepare)(ref.cloud, new_twist)
        if done >= rounds or not twist_changed(new_twist, twist, dt):
            return ref, cur, aligned
        twist = new_twist
