"""Hypothesis draws the same examples on every run (the bench's determinism rule: CI is never flaky);
`HYPOTHESIS_PROFILE=explore ./dev.sh test` searches with fresh random examples instead."""

import os

from hypothesis import settings

settings.register_profile("deterministic", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


def pytest_collection_modifyitems(items):
    """Tests marked `early` run first: the parallel workers then finish together instead of one waiting on a long test started last."""
    items.sort(key=lambda item: item.get_closest_marker("early") is None)
