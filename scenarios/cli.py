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
