"""riverbench: the ground floor every package may import and that imports nothing of ours.

`__version__` is the installed distribution's version ('0+unknown' when it is not installed);
`riverbench.angles` wraps angles, one formula for every package; `riverbench.rng` gives seeded random streams;
errors, atomic writes and provenance live here too. Importing it pins numpy's SIMD and BLAS kernels before numpy loads
(`riverbench.kernels`: the same seed gives the same bytes on AVX2 and AVX-512 machines), so every package imports it first.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from riverbench.kernels import pin

pin()

try:
    __version__ = version("riverbench")
except PackageNotFoundError:
    __version__ = "0+unknown"

__all__ = ["__version__"]
