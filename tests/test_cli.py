"""The command line: the preview job writes its files; bad input is one line and exit code 2."""

import json

import pytest
from typer.testing import CliRunner

from scenarios.cli import app

runner = CliRunner()


def test_worlds_list_names_the_presets():
    result = runner.invoke(app, ["worlds", "list"])
    assert result.exit_code == 0
    assert {"charles_river", "canal_lock", "open_river"} <= set(result.output.split())


def test_preview_writes_picture_cloud_and_summary(tmp_path):
    out = tmp_path / "preview"
    result = runner.invoke(app, ["preview", "canal_lock", "--out", str(out), "--samples", "4", "--quiet"])
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {"preview.png", "scan.pcd", "summary.json", "revolutions.json"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["revolutions"] == 4
    assert summary["points_per_revolution"]["max"] == summary["densest_scan"]["points"] > 0
    assert "by stretch" in result.output and sum(s["revolutions"] for s in summary["by_stretch"].values()) == 4
    assert all(name in result.output for name in summary["by_stretch"])
    assert (out / "preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp leftovers


@pytest.mark.parametrize(
    "args, needle",
    [
        (["preview", "no_such_world"], "no_such_world"),
        (["worlds", "show", "no_such_world"], "no_such_world"),
        (["worlds", "export", "canal_lock", "/proc/no/such/dir/x.ply"], "x.ply"),
    ],
)
def test_bad_input_is_one_line_with_exit_code_2(tmp_path, args, needle):
    if args[0] == "preview":
        args = args + ["--out", str(tmp_path / "out"), "--quiet"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()
