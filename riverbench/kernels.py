"""One set of numeric kernels on every x86-64 machine, so that a seed gives the same bytes on any of them.

numpy picks its SIMD loops, and its OpenBLAS its BLAS and LAPACK kernels, by the CPU it finds when it loads. An
AVX-512 machine gets numpy's x86-64-v4 loops and OpenBLAS's SkylakeX kernels, an AVX2 one the x86-64-v3 loops and the
Haswell kernels (AMD Zen the same code), and the two round sums, products and solves differently in the last bits. A
run amplifies such a bit: a match near a threshold flips, the chained odometry and every filter on it follow. Seed 0
of the library at cf42001 on an AVX-512 AMD EPYC, against the baseline measured on an AVX2 one: bu_truss_bridge gicp
success 0.897 (0.865), ekf yaw p95 1.38 deg (1.20), from OpenBLAS's kernels; rough_water gicp yaw p95 0.733 deg
(0.679) and steer_harvard_bridge ekf APE p95 1.33 m (1.13), from numpy's loops as well. So riverbench asks, before
numpy loads, for numpy's loops up to x86-64-v3 and OpenBLAS's Haswell kernels (AVX2 and FMA), where the CPU has them
and the user has not chosen: every package imports this ground floor first, and the processes a run spawns inherit
the environment.
"""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata
from pathlib import Path

OPENBLAS_CORETYPE = "Haswell"
"""The OpenBLAS kernels every x86-64 run uses (AVX2 + FMA: any x86-64 CPU from 2013 on, Intel or AMD)."""
NUMPY_DISABLED = "X86_V4 AVX512_ICL AVX512_SPR"
"""numpy's dispatched loops above x86-64-v3 (its names from numpy 2.4 on), which every run leaves unused."""
SETTINGS = ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES")
"""The environment variables the two libraries read their kernel choice from when they load."""


def _has_avx2_fma(cpuinfo: Path = Path("/proc/cpuinfo")) -> bool:
    """Whether the CPU reports AVX2 and FMA (Linux's /proc/cpuinfo; False where it cannot be read)."""
    try:
        flags = next((line for line in cpuinfo.read_text().splitlines() if line.startswith("flags")), "").split()
    except OSError:
        return False
    return "avx2" in flags and "fma" in flags


def _numpy_names_levels() -> bool:
    """Whether the installed numpy names its x86 SIMD levels X86_V2..V4 (2.4 and later), without importing it."""
    try:
        major, minor = (int(part) for part in metadata.version("numpy").split(".")[:2])
    except (metadata.PackageNotFoundError, ValueError):
        return False
    return (major, minor) >= (2, 4)


def pin(environ: dict[str, str] | None = None, cpuinfo: Path = Path("/proc/cpuinfo")) -> dict[str, str]:
    """On an x86-64 CPU with AVX2 and FMA, set OPENBLAS_CORETYPE and NPY_DISABLE_CPU_FEATURES where the user has not;
    the two as they stand afterwards (absent: left to the library). Too late once numpy is loaded: `in_force` tells."""
    env = os.environ if environ is None else environ
    if platform.machine().lower() in ("x86_64", "amd64") and _has_avx2_fma(cpuinfo):
        env.setdefault("OPENBLAS_CORETYPE", OPENBLAS_CORETYPE)
        if _numpy_names_levels():
            env.setdefault("NPY_DISABLE_CPU_FEATURES", NUMPY_DISABLED)
    return {key: env[key] for key in SETTINGS if key in env}


_CHOSEN_BEFORE = {key: os.environ[key] for key in SETTINGS if key in os.environ}
"""The kernel settings the user made for this process before riverbench loaded."""
_NUMPY_LOADED_FIRST = "numpy" in sys.modules
"""Whether numpy had loaded (with whatever kernels it found) before riverbench could pin them in this process."""


def in_force() -> str:
    """The kernels this process runs, as provenance records them: 'openblas=<core> numpy-disabled=<features>', each
    'cpu' where the CPU chose (nothing set, or numpy loaded before riverbench could set it)."""
    settled = _CHOSEN_BEFORE if _NUMPY_LOADED_FIRST else os.environ
    return f"openblas={settled.get('OPENBLAS_CORETYPE', 'cpu')} numpy-disabled={settled.get('NPY_DISABLE_CPU_FEATURES', 'none')}"
