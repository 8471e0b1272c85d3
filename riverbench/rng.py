"""Seeded random streams: one numpy Generator per component, derived from the seed and its name."""

from __future__ import annotations

import hashlib

import numpy as np


def stream(seed: int, name: str) -> np.random.Generator:
    """A Generator unique to (seed, name) and stable across runs, machines and Python versions."""
    key = int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), key])))
