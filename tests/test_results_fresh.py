"""Results cannot go stale: docs/results.md and the README's generated block are what benchmarks/results.py makes
from the committed baseline (a refreshed baseline without regenerated tables, or a hand edit, fails here)."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _results_script():
    spec = importlib.util.spec_from_file_location("results_script", ROOT / "benchmarks" / "results.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_generated_tables_are_those_of_the_committed_baseline():
    script = _results_script()
    for path, text in script.generated().items():
        assert path.read_text(encoding="utf-8") == text, (
            f"{path.relative_to(ROOT)} is not what benchmarks/baseline/library.json gives: run `python benchmarks/results.py`"
        )


def test_the_generated_tables_are_stamped_with_the_baselines_commit_and_date():
    from scenarios.score import baseline as baselines

    base = baselines.load(ROOT / "benchmarks" / "baseline" / "library.json")
    results = (ROOT / "docs" / "results.md").read_text(encoding="utf-8")
    commit = base.provenance["git_commit"][:7]
    assert f"commit {commit}" in results and base.created_utc[:10] in results
    assert f"commit {commit}" in (ROOT / "README.md").read_text(encoding="utf-8")
    assert not base.provenance["git_dirty"], "the committed baseline was measured on a tree with uncommitted changes"
