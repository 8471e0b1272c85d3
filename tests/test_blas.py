"""The BLAS kernels riverbench pins: a process that imports it before numpy computes what the Haswell kernels compute,
on any x86-64 CPU with AVX2 (an AVX-512 one included), and a user's own choice stands."""

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from riverbench import blas

ROOT = Path(__file__).resolve().parents[1]
PRODUCTS = """
import hashlib
import numpy as np
rng = np.random.default_rng(0)
out = []
for n in (3, 6, 15, 64):  # the sizes of the filters' and matchers' products and solves, and a larger one
    A, B = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    out += [(A @ B).tobytes(), np.linalg.solve(A, B).tobytes(), np.linalg.eigh(A + A.T)[0].tobytes()]
print(hashlib.sha256(b"".join(out)).hexdigest())
"""
X86_AVX2 = platform.machine().lower() in ("x86_64", "amd64") and blas._has_avx2_fma()


def bytes_of(prelude: str, **env: str) -> str:
    """The digest of PRODUCTS computed in a fresh process after `prelude`, with OPENBLAS_CORETYPE only as `env` says."""
    environ = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"} | {"PYTHONPATH": str(ROOT)} | env
    done = subprocess.run([sys.executable, "-c", prelude + PRODUCTS], env=environ, capture_output=True, text=True, check=True)
    return done.stdout.strip()


@pytest.mark.skipif(not X86_AVX2, reason="riverbench pins kernels only on x86-64 CPUs with AVX2 and FMA")
def test_importing_riverbench_first_computes_what_the_haswell_kernels_compute():
    assert bytes_of("import riverbench\n") == bytes_of("", OPENBLAS_CORETYPE="Haswell")


@pytest.mark.skipif(not X86_AVX2 or "avx512f" not in Path("/proc/cpuinfo").read_text(), reason="needs an AVX-512 CPU")
def test_on_an_avx512_cpu_the_unpinned_kernels_compute_other_bytes():
    # what the pin is for: OpenBLAS's own choice here (SkylakeX) rounds differently, and a run amplifies the bits
    assert bytes_of("") != bytes_of("import riverbench\n")


def test_a_kernel_choice_of_the_users_own_stands(tmp_path):
    assert blas.pin_kernels({"OPENBLAS_CORETYPE": "Zen"}) == "Zen"
    env: dict[str, str] = {}
    expected = blas.CORETYPE if X86_AVX2 else None
    assert blas.pin_kernels(env) == expected and env.get("OPENBLAS_CORETYPE") == expected


def test_a_cpu_without_avx2_or_an_unreadable_cpuinfo_is_left_to_openblas(tmp_path):
    old = tmp_path / "cpuinfo"
    old.write_text("processor\t: 0\nflags\t\t: fpu sse sse2 ssse3 sse4_1 sse4_2 avx\n")
    assert not blas._has_avx2_fma(old)
    assert not blas._has_avx2_fma(tmp_path / "missing")
    modern = tmp_path / "modern"
    modern.write_text("flags\t\t: fpu sse2 avx avx2 fma bmi2\n")
    assert blas._has_avx2_fma(modern)


@pytest.mark.skipif(not X86_AVX2 or blas._CHOSEN_BEFORE not in (None, blas.CORETYPE), reason="pinned on x86-64 with AVX2 unless the user chose")
def test_this_test_session_runs_the_pinned_kernels():
    # the baselines the tests compare against were measured with them (tests/conftest.py imports riverbench first; xdist's
    # workers inherit the pin from the controller)
    assert blas.in_force() == blas.CORETYPE
