"""The replay's live view (riverbench replay --view / --view-save): the recording read back with rerun's own reader against
the replay's run directory (metrics.json's scan count, the <id>.tum tracks, gps.csv's verdicts); a reference places the
scans; a replay without it never loads rerun; bad input is one line; an interrupted replay leaves no recording."""

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import scenarios
from scenarios.cli import app
from scenarios.pipeline import files
from scenarios.pipeline.runner import RunInterrupted

pytest.importorskip("rerun.chunk")
from test_live_view import assert_runs_without_rerun, interrupt_at, read_recording  # after the skip: it needs rerun

runner = CliRunner()
DATA = Path(__file__).parent / "data"
HDL32E = DATA / "pcap" / "monterey-hdl32e-prefix.pcap"
"""VeloView's HDL-32E capture: 7 whole revolutions and 2 GPRMC fixes (tests/test_replay_pcap.py), replayed with quickstart."""
RTK = DATA / "nmea" / "nmea_navsat_driver_rtk_nmea.log"
"""nmea_navsat_driver's RTK log: 120 epochs at 2 Hz, no LiDAR (a GNSS-only replay; tests/test_replay_gnss.py)."""
SHIFT = np.array([3.0, -2.0])
"""How far a test's TUM reference is from the gps_only estimate (m): where the scans are placed instead."""


def replay_args(recording: Path, scenario: str, out: Path, *more: str) -> list[str]:
    """`riverbench replay` of `recording` into `out`, no report, then `more`."""
    return ["replay", str(recording), "--scenario", scenario, "--out", str(out), "--no-report", "--quiet", *more]


def replayed(tmp: Path, recording: Path, scenario: str, *more: str) -> tuple[Path, dict]:
    """Replay with --view-save: the run directory and the recording's rows; no temporary file is left beside them."""
    out, rrd = tmp / "run", tmp / "view.rrd"
    result = runner.invoke(app, replay_args(recording, scenario, out, "--view-save", str(rrd), *more))
    assert result.exit_code == 0, result.output
    assert not [p for p in tmp.iterdir() if p.name.startswith(".")]  # the recording's and the run's temporary names are gone
    return out, read_recording(rrd)


def assert_tracks_are_the_tum_files(out: Path, rows: dict, estimator_ids: list[str]) -> int:
    """Each estimator's /estimators/<id> rows are its <id>.tum rows (time, exact x and y); returns how many rows in all."""
    total = 0
    for eid in estimator_ids:
        expected = files.read_tum(out / f"{eid}.tum", scenario_time=True)
        got = rows.get(f"/estimators/{eid}", [])
        assert len(got) == len(expected), eid
        if not got:
            continue
        assert np.allclose([t * 1e-9 for t, _ in got], expected[:, 0], atol=1e-6)
        xy = np.array([(row["x"][0], row["y"][0]) for _, row in got])
        assert np.abs(xy - expected[:, 1:3]).max() <= 1e-6, eid  # TUM rounds to 1e-6: the values are exact
        drawn = np.array([row["Points3D:positions"][0][:2] for _, row in got])
        assert np.abs(drawn - xy).max() < 1e-3  # the drawn points are float32
        total += len(got)
    return total


def assert_verdicts_are_gps_csv(out: Path, rows: dict, estimator_ids: list[str]) -> None:
    """Each estimator's fixes under /gps/<id>/trusted and /refused are gps.csv's, by its verdict column, at their times and places."""
    with open(out / "gps.csv") as handle:
        fixes = [r for r in csv.DictReader(handle) if r["e"] and r["n"]]
    assert fixes
    logged = 0
    for eid in estimator_ids:
        for verdict, flag in (("trusted", "1"), ("refused", "0")):
            got = rows.get(f"/gps/{eid}/{verdict}", [])
            want = [(float(r["t"]), float(r["e"]), float(r["n"])) for r in fixes if r[f"{eid}.trusted"] == flag]
            assert len(got) == len(want), (eid, verdict)
            for (t, row), (t_csv, east, north) in zip(got, want):
                assert t * 1e-9 == pytest.approx(t_csv, abs=1e-3)
                assert row["Points3D:positions"][0][:2] == pytest.approx((east, north), abs=1e-3)
            logged += len(got)
    assert logged == len(fixes) * len(estimator_ids)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """The HDL-32E capture replayed through quickstart with --view-save: the run directory and the recording's rows."""
    return replayed(tmp_path_factory.mktemp("capture"), HDL32E, "quickstart")


def test_a_replayed_capture_logs_every_scan_the_estimator_tracks_and_the_verdicts(capture):
    out, rows = capture
    ids = [e.id for e in scenarios.load("quickstart").estimators]
    metrics = json.loads((out / "metrics.json").read_text())
    scans = rows.get("/scan", []) + rows.get("/scan_lidar", [])
    assert len(scans) == metrics["run"]["scans"] == 7
    assert all(len(row["Points3D:positions"]) > 1000 for _, row in scans)
    assert assert_tracks_are_the_tum_files(out, rows, ids) > 0
    assert_verdicts_are_gps_csv(out, rows, ids)
    assert not [e for e in rows if e.startswith(("/world", "/truth", "/reference")) or e == "/errors/gps"]  # no world, no truth
    # each scan is placed at the first estimate that is finite (gps_only's here): its lidar pose, the mount above base_link
    placed = {t: row for t, row in rows["/scan"]}
    vessel = {t: np.array(row["Transform3D:translation"][0]) for t, row in rows["/vessel"]}
    track = {t: np.array([row["x"][0], row["y"][0], row["z"][0]]) for t, row in rows["/estimators/gps_only"]}
    assert set(placed) == set(vessel) == set(track)
    assert all(np.allclose(vessel[t], track[t], atol=1e-3) for t in placed)


def test_a_reference_places_the_scans_and_gives_each_estimator_its_distance_to_it(capture, tmp_path):
    """A TUM reference (base_link) SHIFT away from gps_only's track: the scans and the vessel move there, the error is |SHIFT|."""
    out, first = capture
    rows_tum = [line.split() for line in (out / "gps_only.tum").read_text().splitlines() if line and not line.startswith("#")]
    header = [line for line in (out / "gps_only.tum").read_text().splitlines() if line.startswith("#")]
    shifted = [f"{r[0]} {float(r[1]) + SHIFT[0]:.6f} {float(r[2]) + SHIFT[1]:.6f} {' '.join(r[3:])}" for r in rows_tum]
    (tmp_path / "reference.tum").write_text("\n".join(header + shifted) + "\n")
    (tmp_path / "second").mkdir()
    second, rows = replayed(tmp_path / "second", HDL32E, "quickstart", "--reference", str(tmp_path / "reference.tum"))
    reference = files.read_tum(tmp_path / "reference.tum", scenario_time=True)
    got = rows["/reference"]
    assert len(got) == len(rows["/scan"]) == len(reference) == 7
    assert np.abs(np.array([(row["x"][0], row["y"][0]) for _, row in got]) - reference[:, 1:3]).max() < 1e-6
    vessel = np.array([row["Transform3D:translation"][0][:2] for _, row in rows["/vessel"]])
    assert np.abs(vessel - reference[:, 1:3]).max() < 1e-3
    errors = [row["Scalars:scalars"][0] for _, row in rows["/errors/gps_only"] if "Scalars:scalars" in row]
    assert len(errors) == 7 and np.allclose(errors, np.hypot(*SHIFT), atol=1e-5)
    # the scan moved with its placement, rigidly
    for (_, a), (_, b) in zip(first["/scan"], rows["/scan"]):
        delta = np.asarray(b["Points3D:positions"], np.float64) - np.asarray(a["Points3D:positions"], np.float64)
        assert np.abs(delta[:, :2] - SHIFT).max() < 1e-2 and np.abs(delta[:, 2]).max() < 1e-2


def test_an_nmea_only_replay_logs_the_fixes_and_the_tracks_and_no_scan(tmp_path):
    out, rows = replayed(tmp_path, RTK, "canal_multipath", "--reference", str(RTK))
    ids = [e.id for e in scenarios.load("canal_multipath").estimators]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["run"]["gnss_only"] and metrics["run"]["scans"] == 0
    assert "/scan" not in rows and "/scan_lidar" not in rows
    assert assert_tracks_are_the_tum_files(out, rows, ids) > 0
    assert_verdicts_are_gps_csv(out, rows, ids)
    assert len(rows["/reference"]) == metrics["run"]["pose_samples"] == 120  # its own reference: defined at every pose sample


@pytest.mark.parametrize("args, needle", [(["--view-colour", "pink"], "pink"), (["--view-save", "view.txt"], "view.txt")])
def test_bad_replay_view_options_are_one_line_with_exit_code_2_before_anything_runs(tmp_path, args, needle):
    args = [a if not a.endswith((".txt", ".rrd")) else str(tmp_path / a) for a in args]
    result = runner.invoke(app, replay_args(HDL32E, "quickstart", tmp_path / "run", "--view-save", str(tmp_path / "v.rrd"), *args))
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []


def test_a_replay_view_without_rerun_is_the_run_s_one_line(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    result = runner.invoke(app, replay_args(HDL32E, "quickstart", tmp_path / "run", "--view-save", str(tmp_path / "v.rrd")))
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "pip install 'riverbench[view]'" in lines[0] and "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_replay_leaves_no_recording(tmp_path):
    from scenarios.replay import replay
    from scenarios.view.replay_view import ReplayView
    from scenarios.view.sink import ViewSink, ViewTarget

    view = ReplayView(ViewSink(ViewTarget(save=tmp_path / "view.rrd")))
    with pytest.raises(RunInterrupted):
        replay(HDL32E, scenarios.load("quickstart"), tmp_path / "run", report=False, progress=interrupt_at(3), observer=view)
    assert list(tmp_path.iterdir()) == []


def test_a_replay_without_view_does_not_import_rerun(tmp_path):
    assert_runs_without_rerun(replay_args(RTK, "canal_multipath", tmp_path / "run"))
    assert (tmp_path / "run" / "metrics.json").exists()
