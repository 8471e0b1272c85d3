"""One set of BLAS kernels on every x86-64 machine, so that a seed gives the same bytes on any of them.

numpy's OpenBLAS picks its kernels when it loads, by the CPU it finds (or by OPENBLAS_CORETYPE): an AVX-512 machine
gets the SkylakeX kernels, an AVX2 one the Haswell kernels (AMD Zen the same code), and the two round small products
and solves differently in the last bits. A run amplifies such a bit: a match near a threshold flips, a chained
odometry and every filter on it follow. bu_truss_bridge seed 0 at e75e48d: gicp success 0.865, ekf yaw p95 1.20 deg
with the Haswell or Zen kernels (what the committed baseline was measured with), 0.897 and 1.38 deg with SkylakeX's.
So riverbench asks for the Haswell kernels (AVX2 and FMA) before numpy loads, where the CPU has them and the user has
not chosen: every package imports this ground floor first, and processes a run spawns inherit the environment.
"""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path

CORETYPE = "Haswell"
"""The OpenBLAS kernels every x86-64 run uses (AVX2 + FMA: any x86-64 CPU from 2013 on, Intel or AMD)."""


def _has_avx2_fma(cpuinfo: Path = Path("/proc/cpuinfo")) -> bool:
    """Whether the CPU reports AVX2 and FMA (Linux's /proc/cpuinfo; False where it cannot be read)."""
    try:
        flags = next((line for line in cpuinfo.read_text().splitlines() if line.startswith("flags")), "").split()
    except OSError:
        return False
    return "avx2" in flags and "fma" in flags


def pin_kernels(environ: dict[str, str] | None = None) -> str | None:
    """Set OPENBLAS_CORETYPE to CORETYPE on an x86-64 CPU with AVX2 and FMA unless it is set already; the value in
    force afterwards (None: left to OpenBLAS). Too late once numpy is loaded: `in_force` tells."""
    env = os.environ if environ is None else environ
    if "OPENBLAS_CORETYPE" not in env and platform.machine().lower() in ("x86_64", "amd64") and _has_avx2_fma():
        env["OPENBLAS_CORETYPE"] = CORETYPE
    return env.get("OPENBLAS_CORETYPE")


_CHOSEN_BEFORE = os.environ.get("OPENBLAS_CORETYPE")
"""The kernels the user chose for this process before riverbench loaded (None: none)."""
_NUMPY_LOADED_FIRST = "numpy" in sys.modules
"""Whether numpy had loaded (with whatever kernels it found) before riverbench could pin them in this process."""


def in_force() -> str:
    """The OpenBLAS kernels this process runs: the chosen or pinned OPENBLAS_CORETYPE, else 'chosen by the CPU'."""
    if _CHOSEN_BEFORE:
        return _CHOSEN_BEFORE
    pinned = os.environ.get("OPENBLAS_CORETYPE")
    return pinned if pinned and not _NUMPY_LOADED_FIRST else "chosen by the CPU"
