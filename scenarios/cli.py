"""The `riverbench` command line."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from scenarios.errors import one_line

app = typer.Typer(help="riverbench: LiDAR-aided ASV positioning where GPS fails.", no_args_is_help=True)
worlds_app = typer.Typer(help="List, inspect and export the river worlds.", no_args_is_help=True)
app.add_typer(worlds_app, name="worlds")
console = Console()
errors = Console(stderr=True)


@contextmanager
def user_errors() -> Iterator[None]:
    """Bad input ends with one line naming the problem and exit code 2, never a traceback."""
    try:
        yield
    except (ValueError, KeyError, OSError, TypeError) as exc:
        errors.print(f"[bold red]error:[/] {one_line(exc)}", highlight=False, soft_wrap=True)
        raise typer.Exit(2) from None


@app.command()
def preview(
    world: str = typer.Argument("charles_river", help="world preset name or mesh file"),
    out: Path = typer.Option(Path("out/preview"), help="output directory"),
    samples: int = typer.Option(60, min=1, help="revolutions sampled evenly along the route"),
    seed: int = typer.Option(0, help="seed of the motion and sensor noise"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
) -> None:
    """Simulate a world along its route; write preview.png, scan.pcd and summary.json."""
    from scenarios.preview import run_preview

    with user_errors():
        summary = run_preview(world, out, n_samples=samples, seed=seed, quiet=quiet)
    ppr = summary["points_per_revolution"]
    table = Table(title=f"{world}: {summary['revolutions']} revolutions along the route")
    for column in ("points/rev min", "median", "p90", "max", "in 6k-27k", "water share", "ms/rev"):
        table.add_column(column, justify="right")
    table.add_row(
        str(ppr["min"]), f"{ppr['median']:.0f}", f"{ppr['p90']:.0f}", str(ppr["max"]),
        f"{summary['share_in_field_study_band']:.0%}", f"{summary['water_return_share']:.2%}",
        f"{1e3 * summary['seconds_per_revolution_median']:.1f}",
    )
    console.print(table)
    console.print(f"wrote {out}/preview.png, scan.pcd, summary.json")


@worlds_app.command("list")
def worlds_list() -> None:
    """Names of the world presets."""
    import worlds

    for name in worlds.available():
        console.print(name)


@worlds_app.command("show")
def worlds_show(name: str = typer.Argument(..., help="preset name or mesh file")) -> None:
    """Parts, triangles, route length and structures of a world."""
    import json

    import worlds

    with user_errors():
        info = worlds.describe(worlds.load(name))
    console.print_json(json.dumps(info, default=float))


@worlds_app.command("export")
def worlds_export(
    name: str = typer.Argument(..., help="preset name or mesh file"),
    file: Path = typer.Argument(..., help="output mesh file; the format follows the suffix (.ply, .obj, .glb, .stl)"),
) -> None:
    """Write a world's mesh to a file other tools read."""
    import worlds

    with user_errors():
        world = worlds.load(name)
        try:
            worlds.export(world, file)
        except OSError as exc:
            raise OSError(f"cannot write {file}: {exc.strerror or exc}") from exc
    console.print(f"wrote {file}")


scenarios_app = typer.Typer(help="The scenario library: list scenarios, show one resolved.", no_args_is_help=True)
app.add_typer(scenarios_app, name="scenarios")


@app.command()
def run(
    scenario: str = typer.Argument(..., help="library name (riverbench scenarios list) or a .toml path"),
    out: Path = typer.Option(None, help="run directory (default runs/<scenario>-<UTC time>/)"),
    set_: list[str] = typer.Option([], "--set", help="override a field: key=value (TOML value), repeatable"),
    seed: int = typer.Option(None, help="the scenario's seed"),
    workers: int = typer.Option(2, min=1, help="processes: 1 runs everything in one; 2 overlaps matching and simulation"),
    no_report: bool = typer.Option(False, "--no-report", help="skip report.md, report.html and plots/"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
) -> None:
    """Run a scenario: write its run directory, print a summary; exit 1 when an expectation fails."""
    import scenarios
    from scenarios.progress import RunProgress
    from scenarios.runner import RunFailed, RunInterrupted
    from scenarios.summary import run_table

    with user_errors():
        spec = scenarios.load(scenario, set=set_, seed=seed)
    try:
        with RunProgress(spec.name, console, quiet) as progress:
            result = scenarios.run(spec, out, workers=workers, report=not no_report, progress=progress.update)
    except RunInterrupted as exc:
        errors.print(f"[bold yellow]stopped:[/] {exc}", highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    except RunFailed as exc:
        errors.print(f"[bold red]run failed:[/] {exc}", highlight=False, soft_wrap=True)
        raise typer.Exit(1) from None
    except (ValueError, OSError) as exc:
        errors.print(f"[bold red]error:[/] {one_line(exc)}", highlight=False, soft_wrap=True)
        raise typer.Exit(2) from None
    if not quiet:
        console.print(run_table(result))
    target = result.report if result.report.exists() else result.out_dir
    console.print(f"{'all expectations pass' if result.passed else '[bold red]expectations failed[/]'}: {target}")
    raise typer.Exit(0 if result.passed else 1)


@app.command()
def suite(
    scenario: list[str] = typer.Argument(None, help="library names or .toml paths (default: the whole library)"),
    workers: int = typer.Option(2, min=1, help="scenarios run at once"),
    junit: Path = typer.Option(None, help="write JUnit XML here"),
    fast: bool = typer.Option(False, "--fast", help="each scenario's short [fast] variant"),
    out: Path = typer.Option(None, help="directory of the run directories (default runs/suite-<UTC time>/)"),
    timeout: float = typer.Option(3600.0, min=1.0, help="seconds a scenario may take before it counts as failed"),
    quiet: bool = typer.Option(False, "--quiet", help="no per-scenario lines"),
) -> None:
    """Run scenarios as a regression suite; exit 1 when any expectation fails or a scenario crashes."""
    from datetime import datetime, timezone

    import scenarios
    from scenarios.suite import run_suite, write_junit, write_summary
    from scenarios.summary import suite_table

    sources = list(scenario or scenarios.available())
    with user_errors():
        for source in sources:
            scenarios.load(source)
    out = out or Path("runs") / f"suite-{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}"
    with user_errors():
        if out.exists() and any(out.iterdir()):
            raise ValueError(f"output directory {out} exists and is not empty")

    def done(case) -> None:
        if not quiet:
            mark = "[green]pass[/]" if case.passed else "[bold red]FAIL[/]"
            console.print(f"{mark} {case.name} ({case.wall_s:.0f} s){': ' + case.error if case.error else ''}", highlight=False)

    try:
        cases = run_suite(sources, out, workers=workers, fast=fast, timeout_s=timeout, on_done=done)
    except KeyboardInterrupt:
        errors.print("[bold yellow]stopped:[/] suite interrupted; finished scenarios are in " + str(out), highlight=False)
        raise typer.Exit(130) from None
    write_summary(cases, out / "suite.json")
    if junit is not None:
        with user_errors():
            write_junit(cases, junit)
    console.print(suite_table(cases))
    failed = [c.name for c in cases if not c.passed]
    console.print(f"{len(cases) - len(failed)} passed, {len(failed)} failed" + (f": {', '.join(failed)}" if failed else ""))
    raise typer.Exit(1 if failed else 0)


@scenarios_app.command("list")
def scenarios_list() -> None:
    """Names and one-line descriptions of the library's scenarios."""
    import scenarios
    from scenarios.library import read

    table = Table(title="scenario library")
    table.add_column("name")
    table.add_column("description")
    for name in scenarios.available():
        table.add_row(name, str(read(name).get("description", "")))
    console.print(table)


@scenarios_app.command("show")
def scenarios_show(
    name: str = typer.Argument(..., help="library name or .toml path"),
    set_: list[str] = typer.Option([], "--set", help="override a field: key=value"),
) -> None:
    """The resolved scenario (every default filled in) as TOML: what `run` would run."""
    import tomli_w

    import scenarios

    with user_errors():
        spec = scenarios.load(name, set=set_)
    console.print(f"# {spec.name}: resolved, hash {spec.hash}", highlight=False, markup=False)
    console.print(tomli_w.dumps(spec.resolved()), highlight=False, markup=False, soft_wrap=True)


@app.command()
def schema() -> None:
    """The JSON Schema of a scenario file (for editors and validators)."""
    import json

    from scenarios.schema import scenario_json_schema

    print(json.dumps(scenario_json_schema(), indent=2))


if __name__ == "__main__":
    app()
