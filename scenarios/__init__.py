"""The bench users drive: scenario files, the runner, metrics and reports, the CLI.

scenarios.available()                 -> names in the scenario library
scenarios.load("quickstart", set=["lidar.range_noise_m=0.03"], seed=1) -> Scenario
scenarios.run(scenario, "runs/x")     -> RunResult (run directory, metrics, expectations)
"""

from __future__ import annotations

import riverbench  # noqa: F401  (first, before numpy loads: it pins the numeric kernels, riverbench.kernels)


def available() -> list[str]:
    """Names of the library's scenarios."""
    from scenarios.spec.library import available as names

    return names()


def load(name_or_path, set: list[str] | None = None, seed: int | None = None):
    """A validated Scenario from a library name or a TOML path (see scenarios.spec.library.load)."""
    from scenarios.spec.library import load as load_scenario

    return load_scenario(name_or_path, set=set, seed=seed)


def run(scenario, out_dir=None, **options):
    """Run a Scenario and write its run directory (see scenarios.pipeline.runner.run)."""
    from scenarios.pipeline.runner import run as run_scenario

    return run_scenario(scenario, out_dir, **options)


__all__ = ["available", "load", "run"]
