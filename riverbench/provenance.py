"""Where a result came from: riverbench's version and git commit, the platform and the packages that shape the numbers."""

from __future__ import annotations

import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

from riverbench import kernels

KEY_PACKAGES = ("numpy", "scipy", "open3d-cpu", "open3d", "trimesh", "kiss-icp", "small-gicp", "opencv-python-headless", "pymap3d", "pydantic")
"""Distributions whose version can move a metric (the ones absent are left out)."""
SOURCE = Path(__file__).resolve().parent.parent


def collect() -> dict:
    """version, git commit (and whether the tree had uncommitted changes) when run from a checkout, platform, packages."""
    return {
        "riverbench": _version("riverbench") or "unknown",
        **git_state(SOURCE),
        "python": platform.python_version(),
        "platform": f"{platform.system()} {platform.release()} {platform.machine()}",
        "cpus": _cpus(),
        "cpu": cpu_model(),
        "kernels": kernels.in_force(),
        "packages": {name: v for name in KEY_PACKAGES if (v := _version(name))},
    }


def git_state(root: Path) -> dict:
    """{"git_commit": sha, "git_dirty": bool} of the checkout at root; {} when it is none (an installed package)."""
    try:
        sha = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10, check=True)
        status = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, timeout=10, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return {}
    return {"git_commit": sha.stdout.strip(), "git_dirty": bool(status.stdout.strip())}


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def cpu_model() -> str:
    """The processor's model name ('' when the platform does not say): gicp's numbers, and the estimators' that fuse
    them, are not bit-identical across CPU models (measured: 87 of 338 quickstart metrics differ, GPS identical), so a
    baseline records where it was measured."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def other_cpu(measured: dict) -> str | None:
    """'was measured on <model>, this is <model>: ...' when the provenance `measured` names another CPU model than
    this machine's, or other numeric kernels than this process runs (riverbench.kernels: the same model name can cover CPUs
    with and without AVX-512), else None (also when either is unknown)."""
    there, here = measured.get("cpu"), cpu_model()
    if there and here and there != here:
        return f"was measured on {there}, this is {here}: matcher-fed metrics may differ without a code change"
    kernels_there, kernels_here = measured.get("kernels"), kernels.in_force()
    if kernels_there and kernels_there != kernels_here:
        return f"was measured with the kernels {kernels_there}, this runs {kernels_here}: matcher-fed metrics may differ without a code change"
    return None


def _cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def describe(prov: dict) -> str:
    """One line: 'riverbench 0.1.0 at 5f06a21 (+ changes), Python 3.11.7 on Linux x86_64, 2 CPUs'."""
    commit = prov.get("git_commit")
    at = f" at {commit[:7]}{' (+ uncommitted changes)' if prov.get('git_dirty') else ''}" if commit else ""
    return (
        f"riverbench {prov.get('riverbench', '?')}{at}, Python {prov.get('python', '?')} on {prov.get('platform', '?')}, {prov.get('cpus', '?')} CPUs"
    )


def peak_rss_mb() -> float:
    """This process's peak resident memory in MB (NaN where the platform has no POSIX `resource`, e.g. Windows)."""
    try:
        import resource
    except ImportError:
        return float("nan")
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
