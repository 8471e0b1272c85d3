"""The comparison report's figures (scenarios.report.compare.figures): APE per component and configuration with its range
over seeds, and each component's error against time through the GPS-degradation windows. Synthetic runs from the run
report tests (known errors: ekf 1 m off, gps_only holding its position through a blackout at 10-20 s) in two
configurations, one without ekf; and two short real open_river runs without faulty fixes."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
from test_report import BLACKOUT, OFFSET_M
from test_report import make_run as make_full_run

from scenarios.report import compare
from scenarios.report.compare import figures, groups

SEEDS = (0, 1, 2)
NOISES = (0.02, 0.05)


def synthetic_run(run_dir, seed: int, noise: float, without: str | None = None) -> None:
    """The run report's synthetic run as seed `seed` of the configuration lidar.range_noise_m = noise, its APE scaled by
    seed and noise so every configuration has a spread; `without` an estimator (absent from scenario.toml and metrics.json)."""
    make_full_run(run_dir)
    toml = (run_dir / "scenario.toml").read_text().replace("seed = 3", f"seed = {seed}")
    toml = toml.replace("\n[[estimators]]", f"\n[lidar]\nrange_noise_m = {noise}\n\n[[estimators]]", 1)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    metrics["run"] |= {"seed": seed, "scenario_hash": f"h{noise}", "failures": []}
    metrics["matchers"]["icp"]["failed"] = False
    for kind in ("estimators", "matchers"):
        for node in metrics[kind].values():
            for key in ("ape", "ape_aligned"):
                if key in node:
                    node[key] = {k: v * (1.0 + 0.1 * seed + 10.0 * noise) for k, v in node[key].items()}
    if without:
        toml = re.sub(rf'\[\[estimators\]\]\nid = "{without}"\n(?:(?!\[\[)[\s\S])*', "", toml)
        del metrics["estimators"][without]
        (run_dir / f"{without}.tum").unlink()
    (run_dir / "scenario.toml").write_text(toml)
    (run_dir / "metrics.json").write_text(json.dumps(metrics))


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    root = tmp_path_factory.mktemp("figures")
    for noise in NOISES:
        for seed in SEEDS:
            synthetic_run(root / "runs" / f"n{noise}-s{seed}", seed, noise, without="ekf" if noise == NOISES[1] else None)
    return root


@pytest.fixture(scope="module")
def confs(tree):
    return groups.configurations(compare.collect([tree / "runs"]))


def test_the_ape_figure_plots_the_median_and_range_of_metrics_json(tree, confs):
    for kind, path in (("estimators", ("ape", "p95")), ("matchers", ("ape_aligned", "rmse"))):
        rows = figures.ape_rows(confs, kind)
        for row in rows:
            conf = next(c for c in confs if c.title == row.configuration)
            values = [r.metrics[kind][row.component][path[0]][path[1]] for r in conf.runs]
            assert row.spread is not None and row.runs == 3 and row.failures == 0
            assert (row.spread.median, row.spread.lo, row.spread.hi) == (np.median(values), min(values), max(values))
        assert figures.ape_figure(rows, kind, figures.styles(confs)) is not None
    estimators = figures.ape_rows(confs, "estimators")
    assert [(r.configuration, r.component) for r in estimators] == [  # each configuration's components sorted by median
        ("synthetic (lidar.range_noise_m=0.02)", "ekf"),
        ("synthetic (lidar.range_noise_m=0.02)", "gps_only"),
        ("synthetic (lidar.range_noise_m=0.05)", "gps_only"),
    ]


def test_a_component_missing_from_one_configuration_is_left_out_of_it_only(tree, confs):
    assert [c.title for c in confs] == [f"synthetic (lidar.range_noise_m={n})" for n in NOISES]
    assert set(figures.error_curves(confs[0], "estimators")) == {"gps_only", "ekf"}
    assert set(figures.error_curves(confs[1], "estimators")) == {"gps_only"}
    out = tree / "report"
    compare.write([tree / "runs"], out)
    drawn = sorted(p.name for p in (out / "plots").iterdir())
    assert {"ape-estimators.png", "ape-matchers.png", "error-00-synthetic_lidar.range_noise_m=0.02.png"} <= set(drawn)
    assert "error-01-synthetic_lidar.range_noise_m=0.05.png" in drawn
    text = (out / "report.md").read_text()
    for name in drawn:
        assert f"](plots/{name})" in text


def test_the_error_curves_are_each_components_error_with_the_windows(confs):
    curves = figures.error_curves(confs[0], "estimators")
    ekf, held = curves["ekf"], curves["gps_only"]
    assert len(ekf.seeds) == 3 and ekf.t[0] == pytest.approx(1.0)  # ekf has no estimate for the first second
    np.testing.assert_allclose(ekf.median, OFFSET_M, atol=1e-5)
    start, end = BLACKOUT[0] - 100.0, BLACKOUT[1] - 100.0  # the run's first scan is at 100 s
    inside, outside = (held.t > start + 0.05) & (held.t < end - 0.05), (held.t < start - 0.05) | (held.t > end + 0.05)
    assert held.median[inside].min() > 0.1 and held.median[outside].max() < 1e-5  # grows only through the blackout
    (icp,) = figures.error_curves(confs[0], "matchers").values()  # drifting sideways 1 cm per metre: less once aligned
    assert 0.0 < np.nanmax(icp.median) < 0.5 * 0.01 * 2.0 * 40.0
    windows = figures.merged_windows(confs[0])
    assert [(w.kind, w.start, w.end) for w in windows] == [("blackout", 10.0, 20.0), ("reacquisition", 20.0, 21.0)]


def test_seeds_are_put_on_one_grid_by_the_nearest_stamp():
    grid = np.arange(5) * 0.1
    values = figures.on_grid(np.array([0.0, 0.21, 0.4]), np.array([1.0, 2.0, 3.0]), grid)
    np.testing.assert_array_equal(values, [1.0, np.nan, 2.0, np.nan, 3.0])


# ---- real runs ---------------------------------------------------------------------------------------------


def test_two_runs_without_faulty_fixes_get_both_figures(real_runs, tmp_path):
    path = compare.write([real_runs / "runs"], tmp_path / "comparison")
    drawn = sorted(p.name for p in (tmp_path / "comparison" / "plots").iterdir())
    assert {"ape-estimators.png", "error-00-open_river.png"} <= set(drawn)
    assert "ape-matchers.png" not in drawn  # gicp matches nothing in open water: no value, so no empty figure
    page = path.read_text()
    assert len(re.findall(r'<img src="data:image/png;base64,', page)) == len(drawn)


def test_the_error_curves_are_what_metrics_json_scores(real_runs):
    """Each run's curve of each component gives back its metrics.json APE (estimators) and aligned APE (matchers)."""
    (conf,) = groups.configurations(compare.collect([real_runs / "runs"]))
    for kind, key in (("estimators", "ape"), ("matchers", "ape_aligned")):
        for cid, curves in figures.error_curves(conf, kind).items():
            for run, values in zip(conf.runs, curves.seeds):
                node = run.metrics[kind][cid][key]
                finite = values[np.isfinite(values)]
                assert float(np.sqrt(np.mean(finite**2))) == pytest.approx(node["rmse"], abs=2e-3), (cid, run.seed)
                assert float(finite.max()) == pytest.approx(node["max"], abs=2e-3), (cid, run.seed)


def test_a_trajectory_scored_into_one_run_is_drawn_with_its_aligned_ape(real_runs, tmp_path):
    """`riverbench score`'s path: gps_only's poses scored into one seed as odometry (anchor first: a matcher) appear in both
    figures for that seed alone, with the aligned APE metrics.json holds."""
    from scenarios.pipeline import rescore
    from scenarios.score.external import Contract

    shutil.copytree(real_runs / "runs", tmp_path / "runs")
    one = tmp_path / "runs" / "open_river-1"
    rescore.score(one, "mine", one / "gps_only.tum", Contract(anchor="first"), report=False)
    node = json.loads((one / "metrics.json").read_text())["matchers"]["mine"]["ape_aligned"]
    (conf,) = groups.configurations(compare.collect([tmp_path / "runs"]))
    (row,) = [r for r in figures.ape_rows([conf], "matchers") if r.component == "mine"]
    assert row.runs == 1 and row.spread is not None and (row.spread.median, row.spread.n) == (node["rmse"], 1)
    (values,) = figures.error_curves(conf, "matchers")["mine"].seeds
    assert float(np.sqrt(np.nanmean(values**2))) == pytest.approx(node["rmse"], abs=2e-3)
    compare.write([tmp_path / "runs"], tmp_path / "report")
    assert (tmp_path / "report" / "plots" / "ape-matchers.png").exists()
