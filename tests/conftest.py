"""Hypothesis draws the same examples on every run (the bench's determinism rule: CI is never flaky);
`HYPOTHESIS_PROFILE=explore ./dev.sh test` searches with fresh random examples instead."""

import riverbench  # noqa: F401  (first, before numpy loads: it pins the numeric kernels, riverbench.kernels)

# isort: split
import os

import pytest
from hypothesis import settings

settings.register_profile("deterministic", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


def pytest_collection_modifyitems(items):
    """Tests marked `early` run first: the parallel workers then finish together instead of one waiting on a long test started last."""
    items.sort(key=lambda item: item.get_closest_marker("early") is None)


@pytest.fixture(scope="session")
def real_runs(tmp_path_factory):
    """Two seeds of 20 s of open_river, each in runs/open_river-<seed>: no faulty fix (so no ROC), every estimator
    initialised, one matcher (a few seconds each, matchers in this process); the comparison report tests share them."""
    import scenarios

    root = tmp_path_factory.mktemp("real")
    for seed in (0, 1):
        scenario = scenarios.load("open_river", set=["stretch={start_s = 0.0, end_s = 20.0}"], seed=seed)
        scenarios.run(scenario, root / "runs" / f"open_river-{seed}", workers=1, report=False)
    return root
