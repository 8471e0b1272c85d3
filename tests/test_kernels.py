"""The numeric kernels riverbench pins: a process that imports it before numpy computes what numpy's x86-64-v3 loops
and OpenBLAS's Haswell kernels compute, on any x86-64 CPU with AVX2 (an AVX-512 one included); a user's own choice
stands."""

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from riverbench import kernels

ROOT = Path(__file__).resolve().parents[1]
COMPUTED = """
import hashlib
import numpy as np
rng = np.random.default_rng(0)
out = []
for n in (3, 6, 15, 64):  # the sizes of the filters' and matchers' products and solves, and a larger one
    A, B = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    out += [(A @ B).tobytes(), np.linalg.solve(A, B).tobytes(), np.linalg.eigh(A + A.T)[0].tobytes()]
x = 3.0 * rng.standard_normal(100_003)  # numpy's own loops: float64 exp, log and power (AVX-512 has SVML's)
out += [np.exp(x).tobytes(), np.log(np.abs(x)).tobytes(), np.power(np.abs(x), 1.7).tobytes()]
print(hashlib.sha256(b"".join(out)).hexdigest())
"""
X86_AVX2 = platform.machine().lower() in ("x86_64", "amd64") and kernels._has_avx2_fma()
AVX512 = X86_AVX2 and "avx512f" in Path("/proc/cpuinfo").read_text()


def digest(prelude: str, **env: str) -> str:
    """The digest of COMPUTED in a fresh process after `prelude`, with the kernel settings only as `env` gives them."""
    environ = {k: v for k, v in os.environ.items() if k not in kernels.SETTINGS} | {"PYTHONPATH": str(ROOT)} | env
    done = subprocess.run([sys.executable, "-c", prelude + COMPUTED], env=environ, capture_output=True, text=True, check=True)
    return done.stdout.strip()


@pytest.mark.skipif(not X86_AVX2, reason="riverbench pins kernels only on x86-64 CPUs with AVX2 and FMA")
def test_importing_riverbench_first_computes_what_the_pinned_kernels_compute():
    pinned = {"OPENBLAS_CORETYPE": kernels.OPENBLAS_CORETYPE, "NPY_DISABLE_CPU_FEATURES": kernels.NUMPY_DISABLED}
    assert digest("import riverbench\n") == digest("", **pinned)


@pytest.mark.skipif(not AVX512, reason="needs an AVX-512 CPU")
def test_on_an_avx512_cpu_each_unpinned_library_computes_other_bytes():
    # what the pin is for: here OpenBLAS's own choice (SkylakeX) and numpy's AVX-512 loops each round differently
    pinned = digest("import riverbench\n")
    assert digest("", NPY_DISABLE_CPU_FEATURES=kernels.NUMPY_DISABLED) != pinned  # OpenBLAS's choice alone
    assert digest("", OPENBLAS_CORETYPE=kernels.OPENBLAS_CORETYPE) != pinned  # numpy's loops alone


def test_a_kernel_choice_of_the_users_own_stands():
    assert kernels.pin({"OPENBLAS_CORETYPE": "Zen"})["OPENBLAS_CORETYPE"] == "Zen"
    env: dict[str, str] = {}
    settled = kernels.pin(env)
    assert settled == env and (env.get("OPENBLAS_CORETYPE") == kernels.OPENBLAS_CORETYPE) == X86_AVX2


def test_a_cpu_without_avx2_or_an_unreadable_cpuinfo_is_left_to_the_libraries(tmp_path):
    old = tmp_path / "cpuinfo"
    old.write_text("processor\t: 0\nflags\t\t: fpu sse sse2 ssse3 sse4_1 sse4_2 avx\n")
    assert not kernels._has_avx2_fma(old) and not kernels._has_avx2_fma(tmp_path / "missing")
    assert kernels.pin({}, cpuinfo=old) == {}
    modern = tmp_path / "modern"
    modern.write_text("flags\t\t: fpu sse2 avx avx2 fma bmi2\n")
    assert kernels._has_avx2_fma(modern)


@pytest.mark.skipif(
    not X86_AVX2
    or any(kernels._CHOSEN_BEFORE.get(k, v) != v for k, v in zip(kernels.SETTINGS, (kernels.OPENBLAS_CORETYPE, kernels.NUMPY_DISABLED), strict=True)),
    reason="pinned on x86-64 with AVX2 unless the user chose",
)
def test_this_test_session_runs_the_pinned_kernels():
    # the baselines the tests compare against were measured with them (tests/conftest.py imports riverbench first; xdist's
    # workers inherit the pin from the controller)
    assert kernels.in_force() == f"openblas={kernels.OPENBLAS_CORETYPE} numpy-disabled={kernels.NUMPY_DISABLED}"
