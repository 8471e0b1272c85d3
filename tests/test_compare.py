"""The comparison report (scenarios.report.compare) on synthetic run directories written here with known numbers:
two scenarios x two configurations (lidar.range_noise_m 0.02 / 0.05) x three seeds, bridge runs in a
sweep layout and canal runs in suite layouts. ekf beats pf on APE p95 by more than the spread over
seeds under the bridge and within it in the canal; pf fails in one bridge run and the icp matcher in
one canal run; one configuration's gps.csv holds faulty fixes whose ROC is computed by hand below.
One test compares two real open_river runs."""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from scenarios.report import compare
from scenarios.report.compare import groups
from scenarios.report.compare.runs import RunInfo

NOISES = (0.02, 0.05)
SEEDS = (0, 1, 2)
APE_P95 = {  # (scenario, noise) -> estimator -> per seed
    ("bridge", 0.02): {"gps_only": [10.0, 11.0, 12.0], "ekf": [2.6, 2.8, 3.1], "pf": [7.2, 7.5, 7.9]},
    ("bridge", 0.05): {"gps_only": [10.0, 11.0, 12.0], "ekf": [3.0, 3.2, 3.4], "pf": [8.0, 8.5, 9.0]},  # pf fails with seed 2
    ("canal", 0.02): {"gps_only": [10.0, 11.0, 12.0], "ekf": [3.0, 3.5, 4.0], "pf": [3.2, 3.6, 4.4]},
    ("canal", 0.05): {"gps_only": [10.0, 11.0, 12.0], "ekf": [4.0, 4.1, 4.2], "pf": [3.9, 4.0, 5.0]},
}
BLACKOUT = {"gps_only": [20.0, 21.0, 22.0], "ekf": [4.0, 5.0, 6.0], "pf": [3.0, 3.5, 3.8]}  # bridge only
NLOS = {"gps_only": [15.0, 16.0, 17.0], "ekf": [6.0, 7.0, 8.0], "pf": [9.0, 10.0, 11.0]}  # canal only
MATCHERS = {
    "icp": {"success": [0.97, 0.98, 0.99], "hz": [20.0, 22.0, 24.0], "aligned": [0.2, 0.25, 0.3]},
    "bev": {"success": [0.80, 0.85, 0.90], "hz": [100.0, 110.0, 120.0], "aligned": [0.5, 0.6, 0.7]},
}
EKF_RECALL, EKF_FALSE_ALARMS = [0.5, 0.6, 0.7], [0.01, 0.02, 0.03]
PF_FAILS = ("bridge", 0.05, 2)
ICP_FAILS = ("canal", 0.05, 1)
# bridge, noise 0.02: per seed, gps.csv rows (quality, added_err_h, ekf.statistic, ekf.trusted)
FIXES = {
    0: [(1, 8.0, 5.0, 0), (1, 1.0, 1.0, 1), (1, 2.0, 3.0, 0), (0, 9.0, math.nan, 1)],
    1: [(1, 6.0, 2.0, 1), (1, 0.5, 4.0, 0), (6, 7.0, 9.0, 0), (1, 0.2, 0.5, 1)],
    2: [(1, 10.0, 6.0, 0), (1, 0.0, 0.1, 1), (1, 0.0, 0.2, 1), (1, 0.0, 0.3, 1)],
}
# by hand: measured fixes pooled, statistic descending: 6F 5F 4C 3C 2F 1C .5C .3C .2C .1C (3 faulty, 7 clean)
ROC_FA = [0, 0, 0, 1 / 7, 2 / 7, 2 / 7, 3 / 7, 4 / 7, 5 / 7, 6 / 7, 1]
ROC_RECALL = [0, 1 / 3, 2 / 3, 2 / 3, 2 / 3, 1, 1, 1, 1, 1, 1]
OPERATING = (2 / 7, 2 / 3)  # flagged: faulty 8 and 10 m, clean 2 and 0.5 m
TITLES = [f"{s} (lidar.range_noise_m={n})" for s in ("bridge", "canal") for n in NOISES]


def stats(p95: float) -> dict:
    return {"rmse": 0.6 * p95, "mean": 0.5 * p95, "median": 0.5 * p95, "p95": p95, "max": 1.5 * p95}


def window(max_error: float | None) -> dict:
    return {
        "count": int(max_error is not None),
        "seconds": 10.0,
        "max_error": max_error,
        "exit_error": max_error,
        "added": None,
        "recover_s": None,
        "recovered": None,
    }


def scenario_toml(name: str, seed: int, noise: float) -> str:
    return (
        f'name = "{name}"\ndescription = "synthetic {name}"\nseed = {seed}\nworld = "charles_river"\n\n'
        f"[stretch]\nstart_m = 0.0\nend_m = 100.0\n\n[lidar]\nrange_noise_m = {noise}\n\n"
        '[[matchers]]\nid = "icp"\nkind = "gicp"\n\n[[matchers]]\nid = "bev"\nkind = "bev3dof"\n\n'
        '[[estimators]]\nid = "gps_only"\nkind = "gps_only"\nmonitor = "none"\n\n'
        '[[estimators]]\nid = "ekf"\nkind = "ekf"\nmatcher = "icp"\nmonitor = "nis"\n\n'
        '[[estimators]]\nid = "pf"\nkind = "pf"\nmatcher = "icp"\nmonitor = "none"\n'
    )


def metrics_of(name: str, seed: int, noise: float) -> dict:
    i = SEEDS.index(seed)
    failures = []
    estimators = {}
    for eid, values in APE_P95[(name, noise)].items():
        node = {
            "available": 0.85 if (name, noise, eid) == ("bridge", 0.02, "pf") else 1.0,
            "ape": stats(values[i]),
            "rpe_100m": {**stats(1.0), "pairs": 5, "percent": 1.0},
            "yaw": stats(2.0),
            "windows": {
                "blackout": window(BLACKOUT[eid][i] if name == "bridge" else None),
                "nlos": window(NLOS[eid][i] if name == "canal" else None),
                "reacquisition": window(None),
                "injected": window(None),
            },
            "monitor": {
                "added_5m": {
                    "faulty": 3 + i,
                    "recall": EKF_RECALL[i] if eid == "ekf" else 0.0,
                    "false_alarm_rate": EKF_FALSE_ALARMS[i] if eid == "ekf" else 0.0,
                }
            },
            "failed": False,
        }
        if (name, noise, seed) == PF_FAILS and eid == "pf":
            node.update(failed=True, failed_at=12.0)
            failures.append({"component": "estimator", "id": "pf", "stamp": 12.0, "reason": "boom"})
        estimators[eid] = node
    matchers = {
        mid: {
            "success": m["success"][i],
            "gated": 0.0,
            "degenerate": 0.1,
            "hz": m["hz"][i],
            "ms": {"median": 10.0, "p95": 12.0},
            "points": {"median": 8000.0},
            "ape_aligned": stats(m["aligned"][i]),
            "rpe_100m": stats(1.0),
            "yaw": stats(1.0),
            "failed": False,
        }
        for mid, m in MATCHERS.items()
    }
    if (name, noise, seed) == ICP_FAILS:  # only in the run's failure list
        failures.append({"component": "matcher", "id": "icp", "stamp": 5.0, "reason": "bang"})
    return {
        "run": {"scenario": name, "scenario_hash": f"{name}{noise}{seed}".replace(".", ""), "seed": seed, "failures": failures},
        "estimators": estimators,
        "matchers": matchers,
        "expectations": [
            {"expect": "matchers.icp.success > 0.5", "value": 0.9, "pass": True, "reason": ""},
            {"expect": "estimators.ekf.ape.p95 < 3", "value": 3.1 if seed == 1 else 2.9, "pass": seed != 1, "reason": ""},
        ],
    }


def write_gps(path, rows) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["t", "quality", "added_err_h", "gps_only.trusted", "gps_only.statistic", "ekf.trusted", "ekf.statistic", "pf.trusted", "pf.statistic"]
        )
        for k, (quality, added, statistic, trusted) in enumerate(rows):
            w.writerow([f"{0.2 * k:.3f}", quality, added, 1, "0.0000", trusted, "" if math.isnan(statistic) else statistic, 1, "0.0000"])


def make_run(run_dir, name: str, seed: int, noise: float) -> None:
    run_dir.mkdir(parents=True)
    (run_dir / "scenario.toml").write_text(scenario_toml(name, seed, noise))
    (run_dir / "metrics.json").write_text(json.dumps(metrics_of(name, seed, noise), indent=2))
    clean = [(1, 1.0, 0.5, 1)] * 4
    write_gps(run_dir / "gps.csv", FIXES[seed] if (name, noise) == ("bridge", 0.02) else clean)


def make_tree(root) -> None:
    """bridge runs in a sweep directory; canal runs in suite directories (one with a crashed case), plus a run in progress."""
    sweep = root / "sweep"
    sweep.mkdir(parents=True)
    (sweep / "sweep.json").write_text("{}")
    (sweep / "results.csv").write_text("scenario\n")
    for noise in NOISES:
        for seed in SEEDS:
            make_run(sweep / "runs" / f"bridge-{noise}-{seed}", "bridge", seed, noise)
            suite = root / "suites" / f"noise{noise}-seed{seed}"
            make_run(suite / "canal", "canal", seed, noise)
            cases = [{"name": "canal", "run_dir": str(suite / "canal"), "error": ""}]
            if (noise, seed) == (0.02, 0):
                cases.append({"name": "dam_lock", "run_dir": str(suite / "dam_lock"), "error": "timed out after 60 s"})
            (suite / "suite.json").write_text(json.dumps(cases))
    make_run(root / "suites" / ".canal.in_progress", "canal", 0, 0.02)  # hidden: a run being written


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    root = tmp_path_factory.mktemp("compare")
    make_tree(root)
    return root


@pytest.fixture(scope="module")
def written(tree):
    out = tree / "report"
    path = compare.write([tree / "sweep", tree / "suites"], out)
    return path, (out / "report.md").read_text(), path.read_text()


def section(text: str, title: str) -> str:
    """The Markdown of one '## title' section."""
    return text.split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]


def row(text: str, first: str, nth: int = 0) -> list[str]:
    """The cells of the nth Markdown table row starting with `first`."""
    rows = [line for line in text.splitlines() if line.startswith(f"| {first} |")]
    return [c.strip() for c in rows[nth].strip("|").split(" | ")]


# ---- discovery and grouping ---------------------------------------------------------------------------


def test_runs_are_found_in_sweep_and_suite_layouts_and_hidden_ones_skipped(tree):
    runs = compare.collect([tree])
    assert len(runs) == 12
    assert not any(part.startswith(".") for r in runs for part in r.path.relative_to(tree).parts)
    assert sorted((r.scenario, r.seed) for r in compare.collect([tree / "sweep"])) == sorted(("bridge", s) for s in SEEDS for _ in NOISES)
    assert len(compare.collect([tree / "sweep", tree / "sweep" / "runs", tree / "sweep" / "runs" / "bridge-0.02-0"])) == 6  # overlaps once


def test_runs_are_grouped_by_configuration_and_labelled_by_what_differs(tree):
    confs = groups.configurations(compare.collect([tree]))
    assert [c.title for c in confs] == TITLES
    assert all([r.seed for r in c.runs] == list(SEEDS) for c in confs)


def test_labels_name_list_tables_by_id():
    base = {"name": "s", "seed": 0, "matchers": [{"id": "gicp", "kind": "gicp", "params": {"voxel_m": 0.3}}], "expect": ["x < 1"]}
    assert groups.flatten(base) == {"name": "s", "seed": 0, "matchers.gicp.kind": "gicp", "matchers.gicp.params.voxel_m": 0.3, "expect": ["x < 1"]}
    runs = [
        RunInfo(
            Path(f"/nowhere/{v}-{seed}"),
            "s",
            seed,
            "",
            {**base, "seed": seed, "matchers": [{"id": "gicp", "kind": "gicp", "params": {"voxel_m": v}}]},
            {"run": {}},
        )
        for v in (1.0, 0.5)
        for seed in (0, 1)
    ]
    confs = groups.configurations(runs)
    assert [c.title for c in confs] == ["s (matchers.gicp.params.voxel_m=0.5)", "s (matchers.gicp.params.voxel_m=1.0)"]
    assert [len(c.runs) for c in confs] == [2, 2]


def test_labels_leave_out_keys_that_follow_from_another_unless_needed():
    ekf = {"id": "ekf", "kind": "ekf"}
    nis = {"estimators": [{**ekf, "monitor": "nis", "monitor_params": {"gate_prob": 0.999}}]}
    cn0 = {"estimators": [{**ekf, "monitor": "cn0"}]}
    assert groups.label_keys([groups.flatten(nis), groups.flatten(cn0)]) == ["estimators.ekf.monitor"]
    one = {"matchers": [{"id": "gicp", "kind": "gicp"}]}
    two = {"matchers": [{"id": "gicp", "kind": "gicp"}, {"id": "kiss", "kind": "kiss_icp"}]}
    keys = groups.label_keys([groups.flatten(one), groups.flatten(two)])
    assert keys == ["matchers.kiss.kind"]
    assert groups.label_text(groups.flatten(one), keys) == "matchers.kiss.kind=–"


# ---- numbers, ranking, failures ------------------------------------------------------------------------


def test_summary_table_prints_medians_and_ranges_best_in_each_row(tree):
    text = compare.summary_markdown([tree])
    assert row(text, "scenario") == ["scenario", "gps_only", "ekf", "pf"]
    assert [row(text, t)[2:] for t in TITLES] == [
        ["**2.80 (2.60–3.10)**", "7.50 (7.20–7.90)"],
        ["**3.20 (3.00–3.40)**", "8.25 (8.00–8.50) [1 of 3 runs failed]"],
        ["**3.50 (3.00–4.00)**", "3.60 (3.20–4.40)"],
        ["4.10 (4.00–4.20)", "**4.00 (3.90–5.00)**"],  # pf wins canal at 0.05 on the median
    ]
    assert row(text, TITLES[0])[1] == "11.00 (10.00–12.00)"
    assert row(text, "scenario", 1) == ["scenario", "icp", "bev"]
    assert row(text, TITLES[3], 1)[1:] == ["**98.0 % (97.0 %–99.0 %) [1 of 3 runs failed]**", "85.0 % (80.0 %–90.0 %)"]
    assert row(text, TITLES[0], 3)[1:] == ["22.0 (20.0–24.0)", "**110.0 (100.0–120.0)**"]  # speed: bev the faster


def test_per_configuration_tables_with_failure_rates_and_monitor_scores(written):
    text = written[1]
    bridge = section(text, TITLES[1])
    header = ["estimator", "available", "APE rmse (m)", "APE p95 (m)", "APE max (m)", "RPE 100 m (m)", "yaw p95 (°)", "failure rate"]
    assert row(bridge, "estimator") == header
    assert row(bridge, "pf")[3] == "8.25 (8.00–8.50)" and row(bridge, "pf")[-1] == "33.3 % (1/3)"
    assert row(bridge, "ekf")[3] == "**3.20 (3.00–3.40)**" and row(bridge, "ekf")[-1] == "0.0 % (0/3)"
    assert row(bridge, "estimator", 1) == ["estimator", "blackout max (m)", "monitor", "faulty fixes", "recall", "false alarms"]
    assert row(bridge, "pf", 1) == ["pf", "**3.25 (3.00–3.50)**", "none", "–", "–", "–"]  # no monitor: no scores
    assert row(bridge, "ekf", 1) == ["ekf", "5.00 (4.00–6.00)", "nis", "4 (3–5)", "60.0 % (50.0 %–70.0 %)", "2.0 % (1.0 %–3.0 %)"]
    late = section(text, TITLES[0])  # pf starts late
    assert row(late, "pf")[1] == "85.0 % (85.0 %–85.0 %)" and row(late, "ekf")[1] == "**100.0 % (100.0 %–100.0 %)**"
    canal = section(text, TITLES[3])
    assert row(canal, "estimator", 1)[1] == "NLOS max (m)"
    assert row(canal, "icp")[-1] == "33.3 % (1/3)" and row(canal, "bev")[-1] == "0.0 % (0/3)"
    assert row(canal, "icp")[1] == "**98.0 % (97.0 %–99.0 %)**" and row(canal, "icp")[3] == "22.0 (20.0–24.0)"  # failed run left out
    assert "None" not in text and "nan" not in text.lower()


def test_sentences_say_whether_a_win_exceeds_the_spread(written):
    text = written[1]
    assert (
        "Lowest APE p95: ekf 2.80 m (2.60–3.10 over 3 seeds) against pf 7.50 m (7.20–7.90): a clear difference. "
        "Available (share of the scans with an estimate, the scans its errors cover): ekf 100.0 %, pf 85.0 %."
    ) in section(text, TITLES[0])
    assert "Available (" not in section(text, TITLES[1])  # both had an estimate on every scan
    assert "Lowest APE p95: ekf 3.20 m (3.00–3.40 over 3 seeds) against pf 8.25 m (8.00–8.50 over 2 seeds): a clear difference." in section(
        text, TITLES[1]
    )
    assert "Lowest APE p95: ekf 3.50 m (3.00–4.00 over 3 seeds) against pf 3.60 m (3.20–4.40): within the spread: no clear winner." in section(
        text, TITLES[2]
    )
    assert "Highest matching success: icp 98.0 % (97.0 %–99.0 % over 3 seeds) against bev 85.0 % (80.0 %–90.0 %): a clear difference." in text
    summary = section(text, "Summary")
    assert (
        "Lowest APE p95: ekf in 3 of 4 configurations (clear in 2, within the spread in 1); pf in 1 of 4 configurations (within the spread in 1)."
    ) in summary
    assert "Under bridges (worst error in blackout windows): pf in 2 of 2 configurations (clear in 2)." in summary
    assert "Beside walls and in canals (worst error in NLOS windows): ekf in 2 of 2 configurations (clear in 2)." in summary
    assert "Fastest matcher: bev in 4 of 4 configurations (clear in 4)." in summary
    assert (f"Failed: pf (estimator) in 1 of 3 runs of {TITLES[1]}; icp (matcher) in 1 of 3 runs of {TITLES[3]}.") in summary


def test_one_seed_leaves_the_spread_unknown(tree, tmp_path):
    out = tmp_path / "one"
    compare.write([tree / "sweep" / "runs" / "bridge-0.02-1"], out)
    text = (out / "report.md").read_text()
    assert "1 run · 1 scenario (bridge) · 1 configuration · seeds 1" in text
    assert "Lowest APE p95: ekf 2.80 m (1 seed) against pf 7.50 m (1 seed): the spread is unknown (one seed)." in text
    assert row(text, "bridge")[2] == "**2.80**"


def test_an_estimator_failing_in_every_run_prints_dashes(tree, tmp_path):
    run = tmp_path / "src" / "run"
    shutil.copytree(tree / "sweep" / "runs" / "bridge-0.02-0", run)
    metrics = json.loads((run / "metrics.json").read_text())
    metrics["estimators"]["ekf"] = {"failed": True, "ape": None}
    (run / "metrics.json").write_text(json.dumps(metrics))
    compare.write([run], tmp_path / "out")
    text = (tmp_path / "out" / "report.md").read_text()
    assert row(text, "bridge")[2] == "– [1 of 1 runs failed]"
    assert "Lowest APE p95: pf 7.20 m (1 seed) against gps_only 10.00 m (1 seed)" in text


# ---- monitor ROC ---------------------------------------------------------------------------------------


def test_roc_pools_the_measured_fixes_of_all_seeds(tree):
    confs = groups.configurations(compare.collect([tree]))
    roc = confs[0].roc
    assert (roc.measured, roc.faulty) == (10, 3)
    assert [c.eid for c in roc.curves] == ["ekf"]  # gps_only and pf have no monitor
    curve = roc.curves[0]
    np.testing.assert_allclose(curve.false_alarm, ROC_FA)
    np.testing.assert_allclose(curve.recall, ROC_RECALL)
    np.testing.assert_allclose(curve.operating, OPERATING)
    assert all(c.roc.faulty == 0 and not c.roc.curves for c in confs[1:])


def test_one_roc_figure_for_the_configuration_with_faulty_fixes(written, tree):
    plots = sorted(p.name for p in (tree / "report" / "plots").glob("roc-*.png"))
    assert plots == ["roc-00-bridge_lidar.range_noise_m=0.02.png"]
    data = (tree / "report" / "plots" / plots[0]).read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 10_000
    text = written[1]
    assert f"](plots/{plots[0]})" in section(text, TITLES[0])
    assert all("No measured fix had more than 5 m added by the environment: no ROC curve." in section(text, t) for t in TITLES[1:])


# ---- files -----------------------------------------------------------------------------------------------


def test_html_is_self_contained(written):
    page = written[2]
    links = re.findall(r"""\b(?:src|href)\s*=\s*["']([^"']*)""", page, flags=re.IGNORECASE)
    assert len(links) == 3 and all(link.startswith("data:image/png;base64,") for link in links)  # APE of estimators and matchers, one ROC
    assert "<link" not in page and "<script" not in page and "@import" not in page
    for name in ("gps_only", "ekf", "pf", "icp", "bev"):
        assert name in page


def test_runs_list_and_unfinished_suite_cases(written):
    text = written[1]
    assert "12 runs · 2 scenarios (bridge, canal) · 4 configurations · seeds 0–2 (3 per configuration)" in text
    runs = section(text, "Runs")
    missed = "**estimators.ekf.ape.p95 = 3.1 (expected < 3)**"  # each failed expectation: metric, value, bound
    assert row(runs, TITLES[0], 1) == [TITLES[0], "1", "bridge0021", "../sweep/runs/bridge-0.02-1", "**1/2**", missed, ""]
    assert row(runs, TITLES[0], 0)[4:] == ["2/2", "", ""]
    assert row(runs, TITLES[3], 1)[3:] == ["../suites/noise0.05-seed1/canal", "**1/2**", missed, "**icp**"]
    assert row(runs, TITLES[1], 2)[4:] == ["2/2", "", "**pf**"]
    assert sum(line.startswith(("| bridge", "| canal")) for line in runs.splitlines()) == 12
    stopped = section(text, "Runs that did not finish")
    assert row(stopped, "**dam_lock**") == ["**dam_lock**", "timed out after 60 s", "../suites/noise0.02-seed0/suite.json"]


def test_nothing_else_is_left_in_the_output(written, tree):
    out = tree / "report"
    assert sorted(p.name for p in out.iterdir()) == ["plots", "report.html", "report.md"]
    assert not [p for p in tree.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("case", ["missing", "empty", "bad_json", "bad_toml", "run_dir_out"])
def test_bad_input_is_one_line_naming_the_path_and_writes_nothing(tree, tmp_path, case):
    source = tmp_path / "src"
    out = tmp_path / "out"
    if case == "empty":
        (source / "nothing" / "here").mkdir(parents=True)
    elif case in ("bad_json", "bad_toml", "run_dir_out"):
        shutil.copytree(tree / "sweep" / "runs" / "bridge-0.02-0", source / "run")
    if case == "bad_json":
        (source / "run" / "metrics.json").write_text('{"run": {"scenario": "bridge",')
    if case == "bad_toml":
        (source / "run" / "scenario.toml").write_text("name = [")
    if case == "run_dir_out":
        out = source / "run"
    bad = {
        "missing": source,
        "empty": source,
        "bad_json": source / "run" / "metrics.json",
        "bad_toml": source / "run" / "scenario.toml",
        "run_dir_out": out,
    }[case]
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(ValueError) as error:
        compare.write([source], out)
    message = str(error.value)
    assert message.startswith(f"{bad}: ") and "\n" not in message
    assert sorted(tmp_path.rglob("*")) == before


# ---- real runs ---------------------------------------------------------------------------------------------


def test_a_report_on_real_runs_names_every_component(real_runs, tmp_path):
    path = compare.write([real_runs / "runs"], tmp_path / "comparison")
    text = (tmp_path / "comparison" / "report.md").read_text()
    assert path == tmp_path / "comparison" / "report.html" and path.exists()
    assert "2 runs · 1 scenario (open_river) · 1 configuration · seeds 0, 1 (2 per configuration)" in text
    for name in ("gps_only", "hdop_switch", "ekf", "pf", "gicp"):
        assert f"| {name} |" in text
    assert "Open water (open_river), lowest APE p95: " in text
    assert "None" not in text and "nan" not in text.lower()


def test_closed_loop_runs_get_a_vessel_table_with_collisions_over_seeds(tmp_path):
    for steer, clearances in (("ekf", (9.9, 9.5, 10.2)), ("gps_only", (0.0, 4.0, 0.0))):
        for seed, clearance in zip(SEEDS, clearances):
            run_dir = tmp_path / f"steer-{steer}-{seed}"
            make_run(run_dir, "bridge", seed, 0.02)
            toml = (run_dir / "scenario.toml").read_text().replace("\n[lidar]", f'\n[control]\nmode = "closed_loop"\nsteer_on = "{steer}"\n\n[lidar]')
            (run_dir / "scenario.toml").write_text(toml)
            data = json.loads((run_dir / "metrics.json").read_text())
            data["run"]["scenario_hash"] += steer
            data["vessel"] = {
                "collisions": int(clearance == 0.0),
                "min_clearance_m": clearance,
                "time_below_threshold_s": 0.0,
                "cross_track": {"max": 2.0 if steer == "ekf" else 9.0},
            }
            (run_dir / "metrics.json").write_text(json.dumps(data))
    text = (compare.write([tmp_path], tmp_path / "report").parent / "report.md").read_text().split("### Vessel")[1]
    assert row(text, "bridge (control.steer_on=ekf)")[1:4] == ["ekf", "0 of 3", "9.90 (9.50–10.20)"]
    assert row(text, "bridge (control.steer_on=gps_only)")[1:4] == ["gps_only", "**2 of 3**", "0.00 (0.00–4.00)"]


def test_a_configuration_with_another_matcher_is_labelled_by_its_kind_not_its_parameters():
    one = {"matchers": [{"id": "gicp", "kind": "gicp", "params": {"voxel_m": 1.0}}]}
    two = {"matchers": [{"id": "gicp", "kind": "gicp", "params": {"voxel_m": 1.0}}, {"id": "bev", "kind": "bev3dof", "params": {"a": 1, "b": 2}}]}
    flat = [groups.flatten(one), groups.flatten(two)]
    assert groups.label_keys(flat) == ["matchers.bev.kind"]
    assert [groups.label_text(f, ["matchers.bev.kind"]) for f in flat] == ["matchers.bev.kind=–", "matchers.bev.kind=bev3dof"]


def test_a_configuration_whose_runs_report_protection_levels_gets_a_stanford_diagram(tmp_path):
    """Two seeds of the report tests' synthetic run (scans.csv with <id>.hpl): one diagram, the epochs of both pooled."""
    from test_report import make_run as make_full_run

    for seed in (0, 1):
        make_full_run(tmp_path / "runs" / f"s{seed}")
    compare.write([tmp_path / "runs"], tmp_path / "report")
    drawn = sorted(p.name for p in (tmp_path / "report" / "plots").glob("stanford-*.png"))
    assert len(drawn) == 1 and (tmp_path / "report" / "plots" / drawn[0]).read_bytes().startswith(b"\x89PNG")
    text = (tmp_path / "report" / "report.md").read_text()
    assert "### Protection levels" in text and f"](plots/{drawn[0]})" in text and "over the scans of 2 runs, pooled" in text
