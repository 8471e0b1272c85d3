"""The command line: the preview job writes its files; bad input is one line and exit code 2."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

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


def commands(group=None, path=()):
    """Every leaf command of the CLI as (path, click command)."""
    import typer.main

    group = group or typer.main.get_command(app)
    for name, command in getattr(group, "commands", {}).items():
        if getattr(command, "commands", None):
            yield from commands(command, (*path, name))
        else:
            yield (*path, name), command


def test_every_command_takes_quiet_and_its_help_shows_boolean_options_as_flags():
    seen = []
    for path, command in commands():
        seen.append(" ".join(path))
        assert any("--quiet" in p.opts for p in command.params), f"{' '.join(path)} has no --quiet"
        result = runner.invoke(app, [*path, "--help"])
        assert result.exit_code == 0 and "--quiet" in result.output, result.output
        assert "<bool>" not in result.output, f"{' '.join(path)} --help shows a flag as taking a value:\n{result.output}"
        for flag in (p for p in command.params if getattr(p, "is_flag", False)):
            line = next(line for line in result.output.splitlines() if flag.opts[0] in line)
            assert line.split(flag.opts[0])[1][:2] in ("", "  ", " /"), line  # the flag, then its help: no value placeholder
    assert {"run", "suite", "sweep", "report", "export", "replay", "schema", "compare-baselines", "scenarios list", "worlds export"} <= set(seen)
    assert "short [fast] variant" in runner.invoke(app, ["run", "--help"]).output  # help texts are printed as written


def test_run_fast_on_a_scenario_without_a_fast_variant_is_one_line_naming_it_and_exit_2(tmp_path):
    for args, needle in (
        (["run", "open_river", "--fast"], "open_river: no [fast] variant"),
        (["run", "quickstart", "--fast", "--set", "expect=[]"], "expect: overridden, but --fast runs the [fast] table's"),
    ):
        result = runner.invoke(app, [*args, "--out", str(tmp_path / "out"), "--quiet"])
        assert result.exit_code == 2 and needle in result.output and len(result.output.strip().splitlines()) == 1, result.output
    assert list(tmp_path.iterdir()) == []


def test_scenarios_list_and_show_print_each_scenarios_description():
    import scenarios
    from scenarios.spec.library import read

    listed = runner.invoke(app, ["scenarios", "list"])
    flat = " ".join(listed.output.replace("│", " ").split())  # the table wraps long descriptions over lines
    for name in scenarios.available():
        description = read(name)["description"]
        assert description and " ".join(description.split()) in flat, name
        shown = runner.invoke(app, ["scenarios", "show", name])
        assert shown.exit_code == 0 and shown.output.splitlines()[0] == f"# {name}: {description}"
    quiet = runner.invoke(app, ["scenarios", "list", "--quiet"])
    assert quiet.output.split() == scenarios.available()
    assert runner.invoke(app, ["scenarios", "show", "open_river", "--quiet"]).output.startswith('name = "open_river"')


# ---- stopping: Ctrl-C and kill leave nothing behind -------------------------------------------------------

RIVERBENCH = [sys.executable, "-m", "scenarios.cli"]
LONG = "stretch={start_s = 0.0, end_s = 300.0}"
"""Long enough that the run is still streaming when the signal comes (it never runs to the end)."""


def started_writing(directory: Path, deadline_s: float = 120.0) -> Path:
    """The hidden temporary run directory once the run has written into it (its NMEA log is not empty)."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        for tmp in directory.glob(".*"):
            if (tmp / "gps.nmea").is_file() and (tmp / "gps.nmea").stat().st_size > 0:
                return tmp
        time.sleep(0.05)
    raise AssertionError(f"no run started writing in {directory}")


def default_sigint() -> None:
    """What a terminal's foreground job has: the default SIGINT (a shell without job control starts jobs with it ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize(
    ("signum", "to_group", "code"),
    [(signal.SIGTERM, False, 143), (signal.SIGTERM, True, 143), (signal.SIGINT, True, 130)],
    ids=["kill-pid", "kill-group", "ctrl-c"],
)
def test_a_stopped_run_leaves_no_hidden_or_partial_directory_and_exits_128_plus_the_signal(tmp_path, signum, to_group, code):
    proc = subprocess.Popen(
        [*RIVERBENCH, "run", "open_river", "--set", LONG, "--out", "out", "--workers", "2", "--no-report", "--quiet"],
        cwd=tmp_path,
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_sigint,
    )
    try:
        started_writing(tmp_path)
        os.killpg(proc.pid, signum) if to_group else os.kill(proc.pid, signum)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == code, err
    assert f"stopped ({signal.Signals(signum).name})" in err and "nothing written" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # neither the run directory nor its hidden temporary
