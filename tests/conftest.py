"""Hypothesis draws the same examples on every run (the bench's determinism rule: CI is never flaky);
`HYPOTHESIS_PROFILE=explore ./dev.sh test` searches with fresh random examples instead."""

import os

from hypothesis import settings

settings.register_profile("deterministic", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))
