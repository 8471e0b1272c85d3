"""The run report (scenarios.report.run_report, scenarios.report.plots) on a small synthetic run directory written here
with numpy: straight-line truth, an estimator with a known 1 m offset, one that holds its last
position through a GPS blackout, a scan matcher, one passing and one failing expectation."""

from __future__ import annotations

import csv
import json
import math
import re

import numpy as np
import pytest

from scenarios.report import document
from scenarios.report import run_report as report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PLOTS = ("map", "error", "hdop_error", "yaw", "stanford", "matchers")
BLACKOUT = (110.0, 120.0)
HEADING = 0.3  # rad
OFFSET_M = 1.0


def stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    return {
        "rmse": float(np.sqrt(np.mean(v**2))),
        "mean": float(v.mean()),
        "median": float(np.median(v)),
        "p95": float(np.percentile(v, 95)),
        "max": float(v.max()),
    }


def write_tum(path, t, x, y, yaw) -> None:
    rows = np.column_stack([t, x, y, np.zeros_like(t), np.zeros_like(t), np.zeros_like(t), np.sin(yaw / 2), np.cos(yaw / 2)])
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        np.savetxt(f, rows, fmt="%.6f")


def write_csv(path, header, rows) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def make_run(run_dir, scans: int = 400) -> dict:
    """A run directory with every data file a finished run has (no report); returns its metrics."""
    run_dir.mkdir(parents=True, exist_ok=True)
    t = 100.0 + 0.1 * np.arange(scans)
    s = 2.0 * (t - t[0])
    x, y, yaw = 500.0 + s * math.cos(HEADING), 200.0 + s * math.sin(HEADING), np.full(scans, HEADING)
    write_tum(run_dir / "groundtruth.tum", t, x, y, yaw)
    # ekf: 1 m to the left of the truth, 0.5 deg off, no estimate for the first second
    n = np.array([-math.sin(HEADING), math.cos(HEADING)])
    write_tum(run_dir / "ekf.tum", t[10:], x[10:] + OFFSET_M * n[0], y[10:] + OFFSET_M * n[1], yaw[10:] + math.radians(0.5))
    # gps_only: the truth, but holding its last position through the blackout
    held = np.maximum.accumulate(np.where((t >= BLACKOUT[0]) & (t < BLACKOUT[1]), 0, np.arange(scans)))
    write_tum(run_dir / "gps_only.tum", t, x[held], y[held], yaw)
    gps_only_error = np.hypot(x - x[held], y - y[held])
    # icp odometry: a slow yaw drift
    write_tum(run_dir / "icp.tum", t, x, y + 0.01 * s, yaw + 0.001 * np.arange(scans))
    fix_t = t[::2]
    rng = np.random.default_rng(0)
    gps_rows = []
    for k, ft in enumerate(fix_t):
        quality = 0 if BLACKOUT[0] <= ft < BLACKOUT[1] else 1
        err = rng.normal(0, 1.5, 2)
        nlos = int(k % 17 == 0)
        pos = ["", "", ""] if quality == 0 else [f"{x[2 * k] + err[0]:.3f}", f"{y[2 * k] + err[1]:.3f}", "2.000"]
        errs = ["", "", "", ""] if quality == 0 else [f"{err[0]:.3f}", f"{err[1]:.3f}", "0.500", f"{np.hypot(*err):.3f}"]
        gps_rows.append(
            [
                f"{ft:.3f}",
                quality,
                *pos,
                "",
                "",
                "",
                8,
                "" if quality == 0 else "1.20",
                *errs,
                "1.000",
                "" if quality == 0 else "0.300",
                nlos,
                1,
                "0.0000",
                int(quality == 1),
                "1.5000",
            ]
        )
    write_csv(
        run_dir / "gps.csv",
        [
            "t",
            "quality",
            "e",
            "n",
            "u",
            "lat",
            "lon",
            "alt",
            "num_sats",
            "hdop",
            "err_e",
            "err_n",
            "err_u",
            "err_h",
            "open_sky_err_h",
            "added_err_h",
            "nlos_used",
            "gps_only.trusted",
            "gps_only.statistic",
            "ekf.trusted",
            "ekf.statistic",
        ],
        gps_rows,
    )
    keys = ("max_error", "entry_error", "exit_error", "added", "recover_s")
    write_csv(
        run_dir / "windows.csv",
        ["kind", "start", "end", "duration"] + [f"{e}.{k}" for e in ("gps_only", "ekf") for k in keys],
        [
            [
                "blackout",
                *BLACKOUT,
                BLACKOUT[1] - BLACKOUT[0],
                f"{gps_only_error.max():.3f}",
                "0.000",
                f"{gps_only_error.max():.3f}",
                "19.800",
                "0.100",
                "1.000",
                "1.000",
                "1.000",
                "0.000",
                "0.000",
            ],
            ["reacquisition", BLACKOUT[1], BLACKOUT[1] + 1.0, 1.0, "", "", "", "", "", "1.000", "1.000", "1.000", "0.000", ""],
        ],
    )
    scan_rows = [
        [
            f"{t[i]:.3f}",
            f"{x[i]:.3f}",
            f"{y[i]:.3f}",
            "0.000",
            f"{math.degrees(HEADING):.3f}",
            int(i > 0 and i % 50 != 7),
            int(i % 50 == 7),
            int(100 <= i < 120),
            5000 + 10 * (i % 30),
            "12.00",
            "6.000",
            "" if i < 10 else f"{1.5 + 0.01 * i:.3f}",
        ]
        for i in range(scans)
    ]
    header = ["t", "x", "y", "z", "yaw_deg", "icp.ok", "icp.gated", "icp.degenerate", "icp.points", "icp.ms", "gps_only.hpl", "ekf.hpl"]
    write_csv(run_dir / "scans.csv", header, scan_rows)
    (run_dir / "scenario.toml").write_text(
        'name = "synthetic"\ndescription = "a straight line with one bridge"\nseed = 3\n'
        'world = "charles_river"\n\n[stretch]\nstart_s = 100.0\nend_s = 140.0\n\n'
        '[[estimators]]\nid = "gps_only"\nkind = "gps_only"\nmonitor = "none"\n\n'
        '[[estimators]]\nid = "ekf"\nkind = "ekf"\nmonitor = "hdop"\n\n[estimators.monitor_params]\nmax_hdop = 2.0\n'
    )
    window = {
        "count": 1,
        "seconds": 10.0,
        "max_error": float(gps_only_error.max()),
        "exit_error": 19.8,
        "added": 19.8,
        "recover_s": 0.1,
        "recovered": 1.0,
    }
    no_window = {"count": 0, "seconds": 0.0, "max_error": None, "exit_error": None, "added": None, "recover_s": None, "recovered": None}
    monitor = {"faulty": 0, "precision": None, "recall": 0.0, "false_alarm_rate": 0.02, "recall_at_5pct_fa": 0.0}

    def estimator(error, windows):
        return {
            "available": 1.0,
            "ape": stats(error),
            "rpe_10m": {**stats(error), "pairs": 10, "percent": 1.0},
            "rpe_100m": {**stats(error), "pairs": 5, "percent": 1.0},
            "yaw": stats([0.5, 0.5]),
            "windows": {"blackout": windows, "nlos": no_window, "reacquisition": no_window, "injected": no_window},
            "monitor": {"error_5m": monitor, "added_5m": monitor},
            "integrity": {
                "alert_limit_m": 10.0,
                "hpl": stats([6.0]),
                "misleading": 0.01,
                "misleading_epochs": 3,
                "hazardous_epochs": 0,
                "available": 0.9,
            },
            "failed": False,
        }

    metrics = {
        "run": {
            "scenario": "synthetic",
            "scenario_hash": "0123456789abcdef",
            "seed": 3,
            "t_start": float(t[0]),
            "t_end": float(t[-1]),
            "sim_s": float(t[-1] - t[0]),
            "wall_s": 4.0,
            "realtime_factor": 10.0,
            "peak_rss_mb": 300.0,
            "scans": scans,
            "fixes": len(fix_t),
            "workers": 2,
            "lanes": [],
            "failures": [{"component": "matcher", "id": "icp", "stamp": 130.0, "reason": "boom"}],
        },
        "gps": {
            "fixes": len(fix_t),
            "availability": 0.75,
            "valid": 0.75,
            "blackout": 0.25,
            "nlos_share": 0.06,
            "error": stats([1.0, 2.0]),
            "open_sky_error": stats([1.0]),
            "added_error": stats([0.3]),
            "hdop_median": 1.2,
            "faulty_5m": None,
        },
        "estimators": {"gps_only": estimator(gps_only_error, window), "ekf": estimator(np.full(scans - 10, OFFSET_M), {**window, "max_error": 1.0})},
        "matchers": {
            "icp": {
                "success": 0.97,
                "gated": 0.02,
                "degenerate": 0.05,
                "hz": 80.0,
                "ms": {"median": 12.0, "p95": 13.0},
                "points": {"median": 5150.0, "p10": 5000.0, "p90": 5290.0},
                "ape": stats([0.5]),
                "ape_aligned": stats([0.2]),
                "rpe_10m": stats([0.1]),
                "rpe_100m": stats([1.0]),
                "yaw": stats([1.0]),
                "failed": True,
                "failed_at": 130.0,
            }
        },
        "goals": [
            {"goal": "estimators.ekf.ape.p95 <= estimators.gps_only.ape.p95 + 0.1", "value": 1.0, "met": True, "reason": ""},
            {"goal": "estimators.ekf.ape.p95 <= 0.5", "value": 1.0, "met": False, "reason": "estimators.ekf.ape.p95 = 1, expected <= 0.5"},
            {"goal": "estimators.ekf.monitor.added_5m.recall >= 0.95", "value": None, "met": None, "reason": "nothing to measure"},
        ],
        "expectations": [
            {"expect": "estimators.ekf.ape.p95 < 6", "value": 1.0, "pass": True, "reason": ""},
            {
                "expect": "estimators.gps_only.ape.max < 5",
                "value": float(gps_only_error.max()),
                "pass": False,
                "reason": f"estimators.gps_only.ape.max = {gps_only_error.max():.4g}, expected < 5",
            },
        ],
    }
    (run_dir / "metrics.json").write_text(json.dumps(metrics, indent=2))
    return metrics


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "synthetic"
    make_run(out)
    report.write(out)
    return out


def test_every_plot_is_a_valid_png(run_dir):
    for stem in PLOTS:
        data = (run_dir / "plots" / f"{stem}.png").read_bytes()
        assert data.startswith(PNG_SIGNATURE), stem
        assert data[-12:-4] == b"\x00\x00\x00\x00IEND", stem  # complete: ends with the IEND chunk
        assert len(data) > 5_000, stem  # something was drawn


def test_html_is_self_contained(run_dir):
    page = (run_dir / "report.html").read_text()
    links = re.findall(r"""\b(?:src|href)\s*=\s*["']([^"']*)""", page, flags=re.I)
    assert len(links) == len(PLOTS)
    assert all(link.startswith("data:image/png;base64,") for link in links)
    assert "://" not in page and "<link" not in page and "<script" not in page and "@import" not in page
    assert "<title>riverbench: synthetic</title>" in page


def test_html_names_every_estimator_and_the_outcomes(run_dir):
    page = (run_dir / "report.html").read_text()
    for name in ("gps_only", "ekf", "icp"):
        assert name in page
    assert '<td class="pass">PASS</td>' in page
    assert '<td class="fail">FAIL</td>' in page


def test_markdown_holds_expectations_tables_and_plot_links(run_dir):
    text = (run_dir / "report.md").read_text()
    assert text.startswith("# riverbench report: synthetic\n")
    assert "a straight line with one bridge" in text and "seed 3" in text and "0123456789abcdef" in text
    assert "| estimators.ekf.ape.p95 < 6 | 1 | m | PASS |" in text  # the unit of metrics.json's units block
    assert "estimators.gps_only.ape.max < 5" in text and "**FAIL**" in text and "expected < 5" in text
    for stem in PLOTS:
        assert f"](plots/{stem}.png)" in text
    assert "Failures" in text and "boom" in text
    assert "None" not in text and "nan" not in text.lower()
    assert "## Goals" in text and "Goals: 1 of 2 met" in text and "NOT MET" in text and "| n/a |" in text
    assert "### Integrity" in text and "HPL p95 (m)" in text


def test_best_value_per_column_is_bold_and_nulls_are_dashes(run_dir):
    text = (run_dir / "report.md").read_text()
    ekf_rows = [line for line in text.splitlines() if line.startswith("| ekf |")]
    gps_only_rows = [line for line in text.splitlines() if line.startswith("| gps_only |")]
    assert len(ekf_rows) == len(gps_only_rows) == 3  # accuracy, through GPS degradation, integrity
    assert ekf_rows[0].split("|")[3].strip() == f"**{OFFSET_M:.2f}**"  # APE rmse: the 1 m offset beats the blackout's drift
    assert "**" not in gps_only_rows[0].split("|")[3]
    assert ekf_rows[1].split("|")[2].strip() == "**1.00**"  # blackout max
    assert gps_only_rows[1].endswith("| none | – | – | – |")  # no monitor: no faulty count, no recall, no false alarms
    gps_shares = text.split("## GPS\n")[1].strip().split("\n\n")[0]
    assert gps_shares.endswith("| – |")  # faulty_5m is null


def test_nothing_half_written_remains(run_dir):
    leftovers = [p.name for p in [*run_dir.iterdir(), *(run_dir / "plots").iterdir()] if p.name.startswith(".") or p.suffix == ".tmp"]
    assert leftovers == []
    assert all(p.stat().st_mode & 0o777 == 0o644 for p in [run_dir / "report.md", run_dir / "report.html", *(run_dir / "plots").iterdir()])
    assert sorted(p.name for p in (run_dir / "plots").iterdir()) == sorted(f"{s}.png" for s in PLOTS)


def test_rewriting_a_report_replaces_it(run_dir):
    before = {name: (run_dir / name).read_bytes() for name in ("report.md", "report.html")}
    for name in before:
        (run_dir / name).write_text("stale")
    (run_dir / "plots" / "map.png").write_bytes(b"stale")
    report.write(run_dir)
    assert {name: (run_dir / name).read_bytes() for name in before} == before
    assert (run_dir / "plots" / "map.png").read_bytes().startswith(b"\x89PNG")


def test_a_scenario_given_names_the_report(tmp_path):
    import scenarios

    scenario = scenarios.load("quickstart")
    out = tmp_path / "given"
    make_run(out)
    report.write(out, scenario=scenario)
    text = (out / "report.md").read_text()
    assert text.startswith("# riverbench report: quickstart\n")
    assert scenario.description in text and scenario.hash in text


def test_a_run_without_matchers_windows_or_expectations(tmp_path):
    out = tmp_path / "bare"
    metrics = make_run(out)
    metrics["matchers"], metrics["expectations"], metrics["run"]["failures"] = {}, [], []
    (out / "metrics.json").write_text(json.dumps(metrics))
    (out / "windows.csv").write_text("kind,start,end,duration\n")
    (out / "scans.csv").write_text("t,x,y,z,yaw_deg\n")
    report.write(out)
    assert sorted(p.stem for p in (out / "plots").iterdir()) == ["error", "hdop_error", "map", "yaw"]
    text = (out / "report.md").read_text()
    assert "sets no expectations" in text and "No blackout" in text and "Scan matchers" not in text


def degradation_table(monitors: dict[str, tuple[str, dict | None]]) -> document.Table:
    """The run report's 'Through GPS degradation' table of estimators with these (monitor kind, added_5m scores)."""
    nodes = {eid: {"available": 1.0, "ape": {"rmse": 1.0}, **({"monitor": {"added_5m": m}} if m else {})} for eid, (_, m) in monitors.items()}
    info = {"estimators": [{"id": eid, "monitor": kind} for eid, (kind, _) in monitors.items()]}
    blocks = report.estimators(report.Context({"estimators": nodes}, info, {}, 0.0, {}))
    assert isinstance(blocks[-2], document.Heading) and blocks[-2].text == "Through GPS degradation"
    return blocks[-1]


def column(table: document.Table, title: str) -> list[document.Cell]:
    return [row[table.header.index(title)] for row in table.rows]


def test_a_monitor_that_judged_no_faulty_fix_has_no_recall_and_its_false_alarms_are_never_best():
    """As in the quickstart's fast run: no measured fix had more than 5 m added; hdop_switch flagged 6.5 %, ekf 25.6 %."""
    none = {"faulty": 0, "precision": None, "recall": None, "false_alarm_rate": 0.065, "recall_at_5pct_fa": None}
    table = degradation_table(
        {"gps_only": ("none", None), "hdop_switch": ("hdop", none), "ekf": ("combined_cn0", {**none, "false_alarm_rate": 0.256})}
    )
    assert table.header == ["estimator", "monitor", "faulty fixes", "recall", "false alarms"]
    assert [c.text for c in column(table, "recall")] == ["–", "–", "–"]
    assert [c.text for c in column(table, "false alarms")] == ["–", "6.5 %", "25.6 %"]
    assert not any(c.bold for row in table.rows for c in row)
    for statement in ("faulty fixes", "recall", "false alarms"):  # every statement of the caption has its column
        assert statement in table.note and statement in table.header
    assert "window" not in table.note  # no window in this run: no window column, no sentence about one


def test_false_alarms_are_ranked_only_beside_a_recall_above_zero():
    scores = lambda recall, fa: {"faulty": 4, "precision": 0.5, "recall": recall, "false_alarm_rate": fa, "recall_at_5pct_fa": recall}
    table = degradation_table({"a": ("nis", scores(0.5, 0.10)), "silent": ("hdop", scores(0.0, 0.0)), "b": ("cn0", scores(0.75, 0.20))})
    assert [(c.text, c.bold) for c in column(table, "false alarms")] == [("10.0 %", True), ("0.0 %", False), ("20.0 %", False)]
    assert [(c.text, c.bold) for c in column(table, "recall")] == [("50.0 %", False), ("0.0 %", False), ("75.0 %", True)]
    assert [c.text for c in column(table, "faulty fixes")] == ["4", "4", "4"]


def test_every_report_table_states_its_units(run_dir):
    """Each table of the run report gives units in its header or its note (shares carry their '%')."""
    text = (run_dir / "report.md").read_text()
    tables = [block for block in text.split("\n\n") if block.startswith("| ")]
    assert len(tables) >= 7
    for block in tables:
        header = block.splitlines()[0]
        following = text.split(block, 1)[1].lstrip("\n").split("\n\n")[0]
        note = following if following.startswith("*") else ""
        assert re.search(r"\((m|s|ms|°|count)\)|\b(metres|m\)|seconds|units?|share|%)", header + note), header


def test_the_map_projects_the_worlds_parts_onto_the_water_plane():
    """Flat faces fill their footprint, a wall's vertical sheet becomes its line, vegetation and far parts are left out."""
    import trimesh
    from matplotlib.figure import Figure

    from scenarios.report import world_map
    from tests.analytic_worlds import ORIGIN, box, straight_route, water
    from worlds.materials import CONCRETE, SOIL
    from worlds.world import Part, World

    sheet = trimesh.Trimesh([[0, 10, -1], [100, 10, -1], [100, 10, 5], [0, 10, 5]], [[0, 1, 2], [0, 2, 3]])  # the plane y = 10
    parts = [
        water(),
        Part("canal_wall", "wall", CONCRETE, sheet),
        Part("bank", "bank", SOIL, box((100.0, 28.0, 2.0), (50.0, 26.0, 0.0))),
        Part("trunks", "tree", SOIL, box((1.0, 1.0, 8.0), (50.0, 30.0, 4.0))),
        Part("far", "building", CONCRETE, box((10.0, 10.0, 20.0), (5000.0, 5000.0, 10.0))),
    ]
    prints = {f.kind: f for f in world_map.footprints(World("test", parts, straight_route(), ORIGIN), (-20.0, 120.0, -50.0, 50.0))}
    assert sorted(prints) == ["bank", "wall", "water"]
    wall, bank = prints["wall"], prints["bank"]
    assert not len(wall.fill) and len(wall.lines) == 2
    np.testing.assert_allclose(np.sort(wall.lines[:, :, 0].ravel()), [0, 0, 100, 100])
    np.testing.assert_allclose(wall.lines[:, :, 1], 10.0)
    a, b, c = bank.fill[:, 0], bank.fill[:, 1], bank.fill[:, 2]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))
    assert area.sum() == pytest.approx(2 * 100.0 * 28.0)  # top and bottom faces, each the 100 m x 28 m footprint
    assert bank.fill[:, :, 0].min() == 0.0 and bank.fill[:, :, 1].max() == 40.0 and not len(bank.lines)
    ax = Figure().subplots()
    legend = world_map.draw(ax, list(prints.values()))
    assert [p.get_label() for p in legend] == ["water", "bank, ground", "wall (line), quay deck, lock"]
    assert len(ax.collections) == 3  # water and bank filled, the wall a line
