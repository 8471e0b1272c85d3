"""The live view (riverbench run --view / --view-save): the recording read back with rerun's own reader against the
run directory's files and the world's exact geometry; a run without it never loads rerun; bad input is one line."""

import csv
import json
import subprocess
import sys
from collections import defaultdict

import numpy as np
import open3d as o3d
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import scenarios
import worlds
from scenarios.cli import app
from scenarios.pipeline import files
from scenarios.pipeline.runner import RunInterrupted

rr_chunk = pytest.importorskip("rerun.chunk")

runner = CliRunner()
STRETCH = "stretch={start_m = 3950.0, end_m = 3976.0}"
"""quickstart's fast stretch, its first 13 s: every estimator has initialised (10 m of GPS travel), the EKF refuses and trusts fixes."""
TINY = "stretch={start_m = 3950.0, end_m = 3951.0}"
PENCIL_BEAM = "lidar.beam_divergence_mrad=0"
"""No mixed pixels: a footprint straddling a depth edge returns a range between its surfaces, off every mesh (tests/test_lidar_beam.py)."""


def run_args(stretch: str, out, *more: str) -> list[str]:
    """`riverbench run quickstart` over `stretch` into `out`, no expectations, no report, then `more`."""
    return ["run", "quickstart", "--set", stretch, "--set", "expect=[]", "--out", str(out), "--no-report", "--quiet", *more]


def read_recording(path) -> dict[str, list[tuple[int | None, dict]]]:
    """Entity path -> rows (sim_time in ns or None for static data, {component: value}) in time order."""
    rows = defaultdict(list)
    for chunk in rr_chunk.RrdReader(path).stream():
        batch = chunk.to_record_batch().to_pydict()
        times = batch.get("sim_time", [None] * chunk.num_rows)
        for i, t in enumerate(times):
            ns = None if t is None else int(t.value)
            rows[chunk.entity_path].append((ns, {k: v[i] for k, v in batch.items() if k not in ("rerun.controls.RowId", "log_time", "sim_time")}))
    for entity in rows:
        rows[entity].sort(key=lambda row: -1 if row[0] is None else row[0])
    return rows


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """quickstart over STRETCH with --view-save: the run directory, the scenario and the recording's rows."""
    tmp = tmp_path_factory.mktemp("view")
    out, rrd = tmp / "run", tmp / "view.rrd"
    result = runner.invoke(app, run_args(STRETCH, out, "--set", PENCIL_BEAM, "--view-save", str(rrd)))
    assert result.exit_code == 0, result.output
    assert not [p for p in tmp.iterdir() if p.name.startswith(".")]  # the recording's temporary name is gone
    return out, scenarios.load("quickstart", set=[STRETCH, PENCIL_BEAM]), read_recording(rrd)


@pytest.mark.slow
def test_recording_carries_world_scan_tracks_and_fixes_by_verdict(recorded):
    out, scenario, rows = recorded
    world = worlds.load(scenario.world, **scenario.world_params)
    assert {f"/world/{p.name}" for p in world.parts} | {"/world/route", "/vessel/hull"} <= set(rows)
    assert all(t is None for p in world.parts for t, _ in rows[f"/world/{p.name}"])  # the world is static, logged once
    assert {"/scan", "/truth", "/vessel", "/follow", "/errors/gps"} <= set(rows)
    for e in scenario.estimators:
        assert {f"/estimators/{e.id}", f"/errors/{e.id}"} <= set(rows)
        assert f"/gps/{e.id}/trusted" in rows or f"/gps/{e.id}/refused" in rows
    with open(out / "gps.csv") as handle:  # a topic per verdict the run gave
        verdicts = {("trusted" if r["ekf.trusted"] == "1" else "refused") for r in csv.DictReader(handle) if r["e"] and r["n"]}
    assert {f"/gps/ekf/{v}" for v in verdicts} <= set(rows) and "/gps/ekf/trusted" in rows


@pytest.mark.slow
def test_one_scan_frame_per_scan_at_the_scan_times(recorded):
    out, _, rows = recorded
    metrics = json.loads((out / "metrics.json").read_text())
    truth = files.read_tum(out / "groundtruth.tum", scenario_time=True)
    scans = rows["/scan"]
    assert len(scans) == metrics["run"]["scans"] == len(truth) > 0
    assert np.allclose([t * 1e-9 for t, _ in scans], truth[:, 0], atol=1e-6)
    assert all(len(row["Points3D:positions"]) > 0 for _, row in scans)


@pytest.mark.slow
def test_truth_and_estimator_tracks_are_the_run_files(recorded):
    out, scenario, rows = recorded
    for entity, tum in [("/truth", "groundtruth.tum"), *((f"/estimators/{e.id}", f"{e.id}.tum") for e in scenario.estimators)]:
        expected = files.read_tum(out / tum, scenario_time=True)
        got = rows[entity]
        assert len(got) == len(expected) > 0, entity
        assert np.allclose([t * 1e-9 for t, _ in got], expected[:, 0], atol=1e-6)
        xy = np.array([(row["x"][0], row["y"][0]) for _, row in got])
        assert np.abs(xy - expected[:, 1:3]).max() <= 1e-6, entity  # TUM rounds to 1e-6: the values are exact
        drawn = np.array([row["Points3D:positions"][0][:2] for _, row in got])
        assert np.abs(drawn - xy).max() < 1e-3  # the drawn points are float32


@pytest.mark.slow
def test_gps_fixes_by_verdict_are_gps_csv(recorded):
    out, scenario, rows = recorded
    with open(out / "gps.csv") as handle:
        fixes = [r for r in csv.DictReader(handle) if r["e"] and r["n"]]
    assert fixes
    for e in scenario.estimators:
        for verdict, flag in (("trusted", "1"), ("refused", "0")):
            want = [(float(r["t"]), float(r["e"]), float(r["n"])) for r in fixes if r[f"{e.id}.trusted"] == flag]
            got = rows.get(f"/gps/{e.id}/{verdict}", [])
            assert len(got) == len(want), (e.id, verdict)
            for (t, row), (t_csv, east, north) in zip(got, want):
                assert t * 1e-9 == pytest.approx(t_csv, abs=1e-3)
                assert row["Points3D:positions"][0][:2] == pytest.approx((east, north), abs=1e-3)


@pytest.mark.slow
def test_scan_points_lie_on_the_world_surfaces(recorded):
    """Each viewed point, put in the world frame at its firing time's pose, is off the world's mesh only by the range noise."""
    _, scenario, rows = recorded
    world = worlds.load(scenario.world, **scenario.world_params)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(world.mesh.vertices, np.float32)), o3d.core.Tensor(np.asarray(world.mesh.faces, np.uint32)))
    points = np.concatenate([np.asarray(row["Points3D:positions"], np.float32) for _, row in rows["/scan"][::10]])
    distance = scene.compute_distance(o3d.core.Tensor(points)).numpy()
    sigma = scenario.lidar.range_noise_m
    # ~100k points: none is 6 sigma off by chance (p = 2e-9 each); a point is never farther from the surface than its range error
    assert len(points) > 50_000 and np.median(distance) < sigma and distance.max() < 6 * sigma


def test_a_short_recording_has_the_world_a_frame_per_scan_the_true_track_and_the_verdicts(tmp_path):
    """The default tier's sibling of the slow tests above: a 0.5 s stretch."""
    out, rrd = tmp_path / "run", tmp_path / "view.rrd"
    result = runner.invoke(app, run_args(TINY, out, "--view-save", str(rrd), "--workers", "1"))
    assert result.exit_code == 0, result.output
    rows = read_recording(rrd)
    scenario = scenarios.load("quickstart", set=[TINY])
    world = worlds.load(scenario.world, **scenario.world_params)
    assert {f"/world/{p.name}" for p in world.parts} <= set(rows)
    truth = files.read_tum(out / "groundtruth.tum", scenario_time=True)
    assert len(rows["/scan"]) == json.loads((out / "metrics.json").read_text())["run"]["scans"] == len(truth) > 0
    xy = np.array([(row["x"][0], row["y"][0]) for _, row in rows["/truth"]])
    assert np.abs(xy - truth[:, 1:3]).max() <= 1e-6
    for e in scenario.estimators:
        assert f"/gps/{e.id}/trusted" in rows or f"/gps/{e.id}/refused" in rows


def assert_runs_without_rerun(args: list[str]) -> None:
    """`riverbench ARGS` in a fresh interpreter succeeds without importing rerun or scenarios.view."""
    code = (
        "import sys\n"
        "from scenarios.cli import app\n"
        f"try: app({args!r})\n"
        "except SystemExit as done: assert done.code in (0, None), done.code\n"
        "print(sorted(m for m in sys.modules if m == 'rerun' or m.startswith(('rerun.', 'rerun_', 'scenarios.view'))))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_a_run_without_view_does_not_import_rerun(tmp_path):
    assert_runs_without_rerun(run_args(TINY, tmp_path / "run", "--workers", "1"))
    assert (tmp_path / "run" / "metrics.json").exists()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a display is told by DISPLAY / WAYLAND_DISPLAY on Linux only")
def test_view_without_a_display_saves_into_the_run_directory_and_says_so(tmp_path, monkeypatch):
    from scenarios.view import sink

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sink, "listening", lambda port, timeout_s=0.2: False)  # no viewer already running either
    out = tmp_path / "run"
    result = runner.invoke(app, run_args(TINY, out, "--workers", "1", "--view"))
    assert result.exit_code == 0, result.output
    notes = [line for line in result.output.splitlines() if "no viewer" in line]
    assert len(notes) == 1 and str(out / "view.rrd") in notes[0]
    metrics = json.loads((out / "metrics.json").read_text())
    assert len(read_recording(out / "view.rrd")["/scan"]) == metrics["run"]["scans"] > 0


def test_missing_rerun_is_one_line_naming_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    result = runner.invoke(app, ["run", "quickstart", "--set", TINY, "--out", str(tmp_path / "run"), "--view-save", str(tmp_path / "v.rrd")])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "pip install 'riverbench[view]'" in lines[0] and "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, needle", [(["--view-save", "view.txt"], "view.txt"), (["--view-save", "v.rrd", "--view-colour", "pink"], "pink")])
def test_bad_view_options_are_one_line_with_exit_code_2(tmp_path, args, needle):
    args = [a if not a.endswith((".txt", ".rrd")) else str(tmp_path / a) for a in args]
    result = runner.invoke(app, ["run", "quickstart", "--set", TINY, "--out", str(tmp_path / "run"), *args])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and needle in lines[0]
    assert list(tmp_path.iterdir()) == []


def interrupt_at(scans_in: int):
    """A progress callback that presses Ctrl-C once `scans_in` scans are in."""

    def progress(t, t0, t1, scans):
        if scans == scans_in:
            raise KeyboardInterrupt

    return progress


def test_an_interrupted_run_leaves_no_recording(tmp_path):
    from scenarios.view.live import LiveView
    from scenarios.view.sink import ViewSink, ViewTarget

    view = LiveView(ViewSink(ViewTarget(save=tmp_path / "view.rrd")))
    with pytest.raises(RunInterrupted):
        scenarios.run(scenarios.load("quickstart", set=[TINY]), tmp_path / "run", workers=1, report=False, progress=interrupt_at(3), observer=view)
    assert list(tmp_path.iterdir()) == []


@given(st.lists(st.integers(1, 10_000), min_size=1, max_size=30), st.integers(1, 100_000))
def test_the_triangle_cap_is_the_largest_that_fits_the_budget(counts, budget):
    from scenarios.view.world_mesh import triangle_cap

    cap = triangle_cap(counts, budget)
    if sum(counts) <= budget:
        assert cap == max(counts)
    elif budget >= len(counts):
        assert sum(min(n, cap) for n in counts) <= budget < sum(min(n, cap + 1) for n in counts)
    else:
        assert cap == 1  # every part keeps one triangle at least


def test_world_meshes_fit_the_budget_and_keep_every_part():
    from scenarios.view.world_mesh import MATERIAL_COLOURS, part_meshes

    world = worlds.load("canal_lock")
    total = sum(len(p.mesh.faces) for p in world.parts)
    meshes = part_meshes(world, budget=total // 2)
    assert [m.name for m in meshes] == [p.name for p in world.parts]
    assert sum(len(m.faces) for m in meshes) <= total // 2
    for mesh, part in zip(meshes, world.parts):
        assert len(mesh.faces) > 0 and mesh.faces.max() < len(mesh.vertices) == len(mesh.normals)
        assert mesh.colour == MATERIAL_COLOURS[part.material.name]
        assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-6)
        assert (world.mesh.bounds[0] - 1e-6 <= mesh.vertices.min(axis=0)).all()
        assert (mesh.vertices.max(axis=0) <= world.mesh.bounds[1] + 1e-6).all()
