"""The `riverbench` command line."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC
from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from riverbench.errors import one_line
from riverbench.signals import StopSignals

PLAIN_HELP = None
"""Typer's rich_markup_mode for every command's --help: click's plain text. Typer 0.29's rich help lists a boolean
flag as `--fast <bool>`, as if it took a value, and reads the help texts as rich markup (eating '[fast]')."""

app = typer.Typer(help="riverbench: LiDAR-aided ASV positioning where GPS fails.", no_args_is_help=True, rich_markup_mode=PLAIN_HELP)
worlds_app = typer.Typer(help="List, inspect and export the river worlds.", no_args_is_help=True, rich_markup_mode=PLAIN_HELP)
app.add_typer(worlds_app, name="worlds")
console = Console()
errors = Console(stderr=True)


def _print_version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            console.print(f"riverbench {version('riverbench')}", highlight=False)
        except PackageNotFoundError:
            console.print("riverbench (not installed: run from a source tree)", highlight=False)
        raise typer.Exit(0)


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True, help="print the version and exit"),
) -> None:
    """riverbench: LiDAR-aided ASV positioning where GPS fails."""


@contextmanager
def user_errors() -> Iterator[None]:
    """Bad input ends with one line naming the problem and exit code 2, never a traceback."""
    try:
        yield
    except (ValueError, KeyError, OSError, TypeError) as exc:
        errors.print(f"[bold red]error:[/] {escape(one_line(exc))}", highlight=False, soft_wrap=True)
        raise typer.Exit(2) from None


@contextmanager
def stoppable(message: str, interrupted: tuple[type[Exception], ...] = ()) -> Iterator[StopSignals]:
    """Ctrl-C (SIGINT) or `kill` (SIGTERM): the command unwinds, removing its temporaries, says so in one line
    (`message`, or the text of an `interrupted` exception, e.g. a run's RunInterrupted naming the scan) and exits
    128 + the signal's number: 130 or 143."""
    with StopSignals() as stop:
        try:
            yield stop
        except KeyboardInterrupt:
            _stopped(stop, message)
        except interrupted as exc:
            _stopped(stop, str(exc))


def _stopped(stop: StopSignals, message: str) -> None:
    errors.print(f"[bold yellow]stopped[/] ({stop.name}): {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(stop.exit_code) from None


@app.command()
def preview(
    world: str = typer.Argument("charles_river", help="world preset name or mesh file"),
    out: Path = typer.Option(Path("out/preview"), help="output directory"),
    samples: int = typer.Option(60, min=1, help="revolutions sampled evenly along the route"),
    seed: int = typer.Option(0, help="seed of the motion and sensor noise"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
) -> None:
    """Simulate a world along its route; write preview.png, scan.pcd and summary.json."""
    from scenarios.report.preview import run_preview

    with stoppable("preview interrupted; nothing written"), user_errors():
        summary = run_preview(world, out, n_samples=samples, seed=seed, quiet=quiet)
    ppr = summary["points_per_revolution"]
    table = Table(title=f"{world}: {summary['revolutions']} revolutions along the route")
    for column in ("points/rev min", "median", "p90", "max", "in 6k-27k", "water share", "ms/rev"):
        table.add_column(column, justify="right")
    table.add_row(
        str(ppr["min"]),
        f"{ppr['median']:.0f}",
        f"{ppr['p90']:.0f}",
        str(ppr["max"]),
        f"{summary['share_in_field_study_band']:.0%}",
        f"{summary['water_return_share']:.2%}",
        f"{1e3 * summary['seconds_per_revolution_median']:.1f}",
    )
    console.print(table)
    stretches = Table(title="by stretch (route order)")
    for column in ("stretch", "revolutions", "points/rev median", "p10", "p90", "in 6k-27k", "water share"):
        stretches.add_column(column, justify="left" if column == "stretch" else "right")
    for name, st in summary["by_stretch"].items():
        stretches.add_row(
            name,
            str(st["revolutions"]),
            f"{st['median']:.0f}",
            f"{st['p10']:.0f}",
            f"{st['p90']:.0f}",
            f"{st['share_in_field_study_band']:.0%}",
            f"{st['water_return_share']:.2%}",
        )
    console.print(stretches)
    console.print(f"wrote {out}/preview.png, scan.pcd, summary.json")


@worlds_app.command("list")
def worlds_list(quiet: bool = typer.Option(False, "--quiet", help="the names only (what it prints anyway)")) -> None:
    """Names of the world presets."""
    import worlds

    for name in worlds.available():
        console.print(name)


@worlds_app.command("show")
def worlds_show(
    name: str = typer.Argument(..., help="preset name or mesh file"),
    quiet: bool = typer.Option(False, "--quiet", help="the JSON only (what it prints anyway)"),
) -> None:
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
    quiet: bool = typer.Option(False, "--quiet", help="print nothing when it worked"),
) -> None:
    """Write a world's mesh to a file other tools read."""
    import worlds

    with stoppable(f"export interrupted; {file} not written"), user_errors():
        world = worlds.load(name)
        try:
            worlds.export(world, file)
        except OSError as exc:
            raise OSError(f"cannot write {file}: {exc.strerror or exc}") from exc
    if not quiet:
        console.print(f"wrote {file}")


scenarios_app = typer.Typer(help="The scenario library: list scenarios, show one resolved.", no_args_is_help=True, rich_markup_mode=PLAIN_HELP)
app.add_typer(scenarios_app, name="scenarios")


@app.command()
def run(
    scenario: str = typer.Argument(..., help="library name (riverbench scenarios list) or a .toml path"),
    out: Path = typer.Option(None, help="run directory (default runs/<scenario>-<UTC time>/)"),
    set_: list[str] = typer.Option([], "--set", help="override a field: key=value (TOML value), repeatable"),
    seed: int = typer.Option(None, help="the scenario's seed"),
    workers: int = typer.Option(2, min=1, help="processes: 1 runs everything in one; 2 overlaps matching and simulation"),
    no_report: bool = typer.Option(False, "--no-report", help="skip report.md, report.html and plots/"),
    fast: bool = typer.Option(
        False, "--fast", help="run the scenario's short [fast] variant (what `suite --fast` runs); a scenario without one is an error"
    ),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
    view: bool = typer.Option(False, "--view", help="stream the run to the rerun viewer as it happens (running, else spawned); riverbench[view]"),
    view_save: Path = typer.Option(None, "--view-save", help="write the live view to this .rrd file (open: rerun FILE); riverbench[view]"),
    view_colour: str = typer.Option("height", "--view-colour", help="colour the viewed scan by height or intensity"),
) -> None:
    """Run a scenario: write its run directory, print a summary; exit 1 when an expectation fails, 130/143 on
    Ctrl-C/SIGTERM (nothing written)."""
    import scenarios
    from scenarios.pipeline.progress import RunProgress
    from scenarios.pipeline.runner import RunFailed, RunInterrupted, default_out_dir
    from scenarios.report.summary import failed_components, run_table
    from scenarios.spec.library import load_fast

    with stoppable("run interrupted; nothing written", (RunInterrupted,)):
        with user_errors():
            spec = (load_fast if fast else scenarios.load)(scenario, set=set_, seed=seed)
            out = out if out is not None else default_out_dir(spec)
            observer = _live_view(view, view_save, view_colour, out, "run") if view or view_save is not None else None
        try:
            with RunProgress(spec.name, console, quiet) as progress:
                result = scenarios.run(spec, out, workers=workers, report=not no_report, progress=progress.update, observer=observer)
        except RunFailed as exc:
            errors.print(f"[bold red]run failed:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None
        except (ValueError, OSError) as exc:
            errors.print(f"[bold red]error:[/] {escape(one_line(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
    if not quiet:
        console.print(run_table(result))
    target = result.report if result.report.exists() else result.out_dir
    failed = failed_components(result.metrics)
    note = f" ([bold red]failed during the run:[/] {escape('; '.join(failed))})" if failed else ""
    console.print(f"{'all expectations pass' if result.passed else '[bold red]expectations failed[/]'}: {target}{note}")
    raise typer.Exit(0 if result.passed else 1)


def _live_view(view: bool, save: Path | None, colour: str, out: Path, what: str):
    """The live view (scenarios.view) of a run (`what` "run": LiveView) or a replay ("replay": ReplayView): one line and exit 2
    without the rerun SDK or with a bad colour; one line when --view finds no viewer."""
    from scenarios.view import import_rerun

    import_rerun()
    from scenarios.view.live import LiveView
    from scenarios.view.replay_view import ReplayView
    from scenarios.view.sink import FALLBACK_NAME, ViewSink, ViewTarget

    sink = ViewSink(ViewTarget(viewer=view, save=save))
    observer = (LiveView if what == "run" else ReplayView)(sink, colour)
    why = sink.connect()
    if why is not None:
        where = save if save is not None else out / FALLBACK_NAME
        note = f"{why}; saving the view to {where} (open it with: rerun {where})"
        errors.print(f"[bold yellow]no viewer:[/] {escape(note)}", highlight=False, soft_wrap=True)
    return observer


@app.command()
def suite(
    scenario: list[str] = typer.Argument(None, help="library names or .toml paths (default: the whole library)"),
    workers: int = typer.Option(2, min=1, help="scenarios run at once"),
    junit: Path = typer.Option(None, help="write JUnit XML here"),
    fast: bool = typer.Option(
        None,
        "--fast/--full",
        show_default=False,
        help="each scenario's short [fast] variant, or the full one (default: full; with --baseline, as the baseline ran)",
    ),
    seeds: int = typer.Option(
        None,
        min=1,
        show_default=False,
        help="run each scenario on this many seeds (its own and the next); default 1, 5 with --save-baseline, "
        "with --baseline the baseline's (or its first N)",
    ),
    set_: list[str] = typer.Option([], "--set", help="override a field in every scenario: key=value, repeatable"),
    save_baseline: Path = typer.Option(None, "--save-baseline", help="store every metric of every seed's run in this baseline file"),
    baseline: Path = typer.Option(None, "--baseline", help="judge every metric against this baseline file; exit 1 on a regression"),
    out: Path = typer.Option(None, help="directory of the run directories (default runs/suite-<UTC time>/)"),
    timeout: float = typer.Option(3600.0, min=1.0, help="seconds a scenario may take before it counts as failed"),
    quiet: bool = typer.Option(False, "--quiet", help="no per-scenario lines"),
) -> None:
    """Run scenarios as a regression suite; exit 1 when an expectation fails, a scenario crashes or (--baseline) a metric regressed."""
    from datetime import datetime

    import scenarios
    from riverbench import provenance
    from scenarios.batch import outcome
    from scenarios.batch.suite import run_suite, write_junit, write_summary
    from scenarios.report.summary import regression_table, suite_table
    from scenarios.score import baseline as baselines

    with user_errors():
        stored = baselines.load(baseline) if baseline is not None else None
        sources = list(scenario or scenarios.available())
        loaded = {source: scenarios.load(source, set=set_) for source in sources}
        names = {source: spec.name for source, spec in loaded.items()}
        if stored is not None:
            fast = _as_baseline(fast, stored, baseline)
            if not set(names.values()) & set(stored.scenarios):
                raise ValueError(f"baseline {baseline} has none of these scenarios (it has: {', '.join(sorted(stored.scenarios))})")
        fast = bool(fast)
        jobs = _suite_jobs(sources, names, seeds, stored, save_baseline is not None, tuple(set_))
        out = out or Path("runs") / f"suite-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"
        if out.exists() and any(out.iterdir()):
            raise ValueError(f"output directory {out} exists and is not empty")

    def done(case) -> None:
        if not quiet:
            if case.error:
                mark = "[bold red]failed to run[/]"
            else:
                failed = sum(not e["pass"] for e in case.expectations)
                mark = f"[bold red]FAIL[/] ({failed} of {len(case.expectations)} expectations)" if failed else "[green]pass[/]"
            console.print(f"{mark} {escape(case.label)} ({case.wall_s:.0f} s){': ' + escape(case.error) if case.error else ''}", highlight=False)

    note = provenance.other_cpu(stored.provenance) if stored is not None else None
    if note:
        console.print(f"note: the baseline {note}", highlight=False, markup=False)
    if fast:
        full = sorted({spec.name for spec in loaded.values() if spec.fast is None})
        if full:  # as the library's baseline was measured; `run --fast` and `sweep --fast` refuse such a scenario
            console.print(f"--fast: no [fast] variant, so run in full: {', '.join(full)}", highlight=False, markup=False)
    stopped = "suite interrupted; finished scenarios are in " + str(out) + ("; no baseline written" if save_baseline else "")
    with stoppable(stopped):
        cases = run_suite(jobs, out, workers=workers, fast=fast, timeout_s=timeout, on_done=done)
        comparison = None
        if stored is not None or save_baseline is not None:
            measured = baselines.from_cases(cases, fast=fast, overrides=list(set_), provenance=provenance.collect())
            if save_baseline is not None:
                with user_errors():
                    measured.save(save_baseline)
            if stored is not None:
                from scenarios.score.regression import compare

                comparison = compare(stored, measured)
        write_summary(cases, out / "suite.json", comparison)
        if junit is not None:
            with user_errors():
                write_junit(cases, junit, comparison)
    console.print(suite_table(cases))
    verdict = outcome.of_cases(cases)
    for line in verdict.lines():
        console.print(line, highlight=False, markup=False)
    if save_baseline is not None:
        broken = sum(bool(c.error) for c in cases)
        console.print(
            f"wrote baseline {save_baseline}: {len({c.name for c in cases})} scenarios x {len(jobs) // max(len(sources), 1)} seeds"
            + (f" ([bold red]{broken} runs failed[/]: their metrics are null)" if broken else ""),
            highlight=False,
        )
    if comparison is not None:
        from scenarios.report import compare as comparing

        console.print(regression_table(comparison))
        with stoppable(f"comparison report interrupted; not written (suite.json is in {out})"):
            page = comparing.write([out], out / "comparison", against=comparison)
        console.print(f"comparison report: {page}", highlight=False)
    raise typer.Exit(1 if not verdict.passed or (comparison is not None and comparison.failed) else 0)


def _as_baseline(fast: bool | None, stored, path: Path) -> bool:
    """--fast/--full as the baseline ran (a mismatch is bad input: the numbers would not be comparable)."""
    if fast is not None and fast != stored.fast:
        raise ValueError(f"baseline {path} ran the {'fast' if stored.fast else 'full'} variants; drop --{'full' if fast is False else 'fast'}")
    return stored.fast


def _suite_jobs(sources: list[str], names: dict[str, str], seeds: int | None, stored, saving: bool, overrides: tuple[str, ...]) -> list:
    """The suite's runs: one per scenario as before, or per scenario and seed (a baseline's seeds when comparing)."""
    from scenarios import load
    from scenarios.batch.suite import Job, jobs_for

    if stored is None and seeds is None and not saving:
        return jobs_for(sources, None, overrides)
    count = seeds or (5 if stored is None else None)
    jobs = []
    for source in sources:
        runs = stored.scenarios.get(names[source]) if stored is not None else None
        if runs is not None:
            if count is not None and count > len(runs.seeds):
                raise ValueError(f"--seeds {count}: the baseline ran {names[source]} on {len(runs.seeds)} seeds")
            chosen = runs.seeds[:count]
        else:
            first = load(source).seed
            chosen = list(range(first, first + (count or _baseline_seed_count(stored))))
        jobs += [Job(source, s, overrides, f"{names[source]}/seed-{s}") for s in chosen]
    return jobs


def _baseline_seed_count(stored) -> int:
    """How many seeds a scenario new since the baseline runs on: as many as the baseline's scenarios mostly have."""
    counts = [len(r.seeds) for r in stored.scenarios.values()]
    return max(set(counts), key=counts.count) if counts else 1


@app.command("compare-baselines")
def compare_baselines(
    base: Path = typer.Argument(..., help="the reference baseline file (e.g. main's)"),
    new: Path = typer.Argument(..., help="the baseline file to judge (e.g. a feature branch's)"),
    seeds: int = typer.Option(None, min=1, show_default=False, help="compare on the first N seeds both have (default all)"),
    junit: Path = typer.Option(None, help="write JUnit XML here (a testcase per scenario and metric family)"),
    out: Path = typer.Option(None, help="write report.md and report.html of the comparison into this directory"),
    json_out: Path = typer.Option(None, "--json", help="write the comparison as JSON here"),
    quiet: bool = typer.Option(False, "--quiet", help="the one-line verdict instead of the table"),
) -> None:
    """Compare two stored baselines without running anything; exit 1 when a metric regressed."""
    import json

    from riverbench.atomic import atomic_path
    from scenarios.batch.suite import write_junit
    from scenarios.report.summary import regression_table
    from scenarios.score import baseline as baselines
    from scenarios.score.regression import compare

    with stoppable("comparison interrupted; nothing written"), user_errors():
        a, b = baselines.load(base), baselines.load(new)
        if a.fast != b.fast:
            raise ValueError(
                f"{base} ran the {'fast' if a.fast else 'full'} variants and {new} the {'fast' if b.fast else 'full'} ones: "
                "their numbers are not comparable"
            )
        if not set(a.scenarios) & set(b.scenarios):
            raise ValueError(f"{base} and {new} have no scenario in common")
        comparison = compare(a, b, seeds)
        if junit is not None:
            write_junit([], junit, comparison)
        if json_out is not None:
            with atomic_path(json_out) as tmp:
                tmp.write_text(json.dumps(comparison.as_dict(), indent=2) + "\n")
        if out is not None:
            from scenarios.report import compare as comparing

            console.print(f"comparison report: {comparing.write_against(comparison, out)}", highlight=False)
    console.print(comparison.sentence() if quiet else regression_table(comparison), highlight=False)
    raise typer.Exit(1 if comparison.failed else 0)


@app.command()
def sweep(
    scenario: list[str] = typer.Argument(None, help="library names or .toml paths, every point runs on each (default: the whole library)"),
    grid: list[str] = typer.Option([], "--grid", help="key=v1,v2,... (TOML values); repeat for a cartesian grid"),
    sample: tuple[int, str] = typer.Option(
        (0, ""),
        "--sample",
        show_default=False,
        help="N key=lo:hi[:log][,key2=lo:hi...]: N joint points in the keys' box (linear, or log-scaled with :log), placed by --sampler",
    ),
    sampler: str = typer.Option("lhs", help="how --sample places its points: lhs (Latin hypercube), sobol (scrambled; N a power of 2) or random"),
    sample_seed: int = typer.Option(0, help="seed of the --sample points"),
    seeds: int = typer.Option(1, min=1, help="repeat every point over this many seeds (the scenario's seed and the next)"),
    set_: list[str] = typer.Option([], "--set", help="fix a field for every run: key=value, repeatable"),
    fast: bool = typer.Option(False, "--fast", help="run each scenario's short [fast] variant; a scenario without one is an error"),
    workers: int = typer.Option(2, min=1, help="runs at once (local: processes; ray: CPUs of a local Ray instance)"),
    backend: str = typer.Option("local", help="local (process pool) or ray"),
    address: str = typer.Option(None, help="address of an existing Ray cluster (default: start a local instance)"),
    out: Path = typer.Option(None, help="sweep directory (default runs/sweep-<UTC time>/); give an existing one to resume it"),
    objective: str = typer.Option(None, help="metric to rank parameters by, a dotted path of metrics.json"),
    maximize: bool = typer.Option(False, "--maximize/--minimize", help="whether a higher objective is better"),
    plot: list[str] = typer.Option([], "--plot", help="also plot this metric against each swept parameter, repeatable"),
    lean: bool = typer.Option(False, "--lean", help="skip each run's report and plots (metrics and data files are kept)"),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="run again the points whose earlier run failed to run"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar or per-run lines"),
) -> None:
    """Run a parameter sweep: a results table (Parquet and CSV), a run directory per run, plots, the best parameters;
    exit 1 when a run failed to run or failed an expectation, 130/143 on Ctrl-C/SIGTERM (the same command resumes it)."""
    from datetime import datetime

    import scenarios
    from scenarios.batch import outcome
    from scenarios.batch import sweep as sweeping
    from scenarios.batch.plan import Axis, Range, SweepPlan
    from scenarios.batch.progress import SweepProgress, summary

    with user_errors():
        if backend not in ("local", "ray"):
            raise ValueError(f"--backend {backend!r}: use local or ray")
        if address and backend != "ray":
            raise ValueError("--address is for --backend ray")
        if backend == "ray":
            from scenarios.batch.ray_backend import import_ray

            import_ray()
        count, ranges = sample
        plan = SweepPlan(
            tuple(scenario or scenarios.available()),
            tuple(Axis.parse(g) for g in grid),
            tuple(Range.parse(r) for r in ranges.split(",") if r.strip()) if ranges else (),
            samples=count,
            seeds=seeds,
            fixed=tuple(set_),
            sample_seed=sample_seed,
            sampler=sampler,
            fast=fast,
        )
        if count and not ranges:
            raise ValueError(f"--sample {count}: name what to sample, e.g. --sample {count} lidar.range_noise_m=0.01:0.05")
        points = plan.points()
        for option, metric in [("--objective", objective), *(("--plot", m) for m in plot)]:
            if metric:
                sweeping.check_metric(metric, points, option)
        out = out or Path("runs") / f"sweep-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"
        sweeping.check_out_dir(out)
    if not quiet:
        console.print(
            f"sweep: {len(points)} runs ({len(plan.combinations())} parameter combinations x "
            f"{len(plan.sources)} scenario(s) x {seeds} seed(s)) into {out}",
            highlight=False,
        )
    progress = SweepProgress(console, quiet)
    with stoppable(f"sweep interrupted; the finished runs are in {out}/results.csv; the same command completes it"):
        try:
            with progress:
                result = sweeping.run_sweep(
                    plan,
                    out,
                    workers=workers,
                    backend=backend,
                    address=address,
                    lean=lean,
                    retry_failed=retry_failed,
                    points=points,
                    on_start=progress.start,
                    on_row=progress.row,
                )
        except (ValueError, OSError) as exc:
            errors.print(f"[bold red]error:[/] {escape(one_line(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        written = sweeping.write_plots(result, plan, objective, plot)
    console.print(summary(result, plan, objective, not maximize, written), highlight=False)
    raise typer.Exit(outcome.of_rows(result.rows).exit_code)


@app.command()
def report(
    dirs: list[Path] = typer.Argument(..., help="run directories, suite or sweep outputs, or any directory holding run directories"),
    out: Path = typer.Option(None, help="report directory (default runs/report-<UTC time>/)"),
    quiet: bool = typer.Option(False, "--quiet", help="print only the report's path"),
) -> None:
    """Compare estimators and matchers over runs: report.md and a self-contained report.html, ranked per scenario."""
    from datetime import datetime

    from scenarios.report import compare

    out = out or Path("runs") / f"report-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"
    with stoppable("report interrupted; nothing written"), user_errors():
        if out.exists() and any(out.iterdir()):
            raise ValueError(f"output directory {out} exists and is not empty")
        page = compare.write(list(dirs), out)
    if not quiet:
        for sentence in compare.summary_sentences(list(dirs)):
            console.print(sentence, highlight=False, markup=False)
    console.print(f"wrote {page} and report.md", highlight=False)


@app.command()
def study(
    out: Path = typer.Option(None, help="study directory (default runs/study-<UTC time>/)"),
    seed: int = typer.Option(None, help="the scenario's seed (default charles_river's)"),
    stretch: str = typer.Option(None, help="START:END route stations in metres (default the whole route, BU Bridge to Charlestown Bridge)"),
    workers: int = typer.Option(2, min=1, help="processes (1: everything in this one)"),
    setup: str = typer.Option(
        "both",
        help="bench (the library scenario as it is), field (the field study's receiver, GPS alone, and its Method 1, "
        "pre-aligned on every pair) or both, side by side",
    ),
    scenario_file: Path = typer.Option(
        None,
        "--scenario",
        help='a scenario file whose command components (kind = "command" in [[matchers]] or [[estimators]]) are run on the '
        "study's stretch and scored beside the built-ins in the findings they apply to (matchers: e, f, h; estimators: b, d)",
    ),
    findings_: str = typer.Option(None, "--findings", help="with --scenario: score the command components in these findings only, e.g. f,h"),
    set_: list[str] = typer.Option(
        [],
        "--set",
        help="override a field of the study's charles_river scenario under every setup: key=value (TOML value), "
        "repeatable, e.g. vessel.wind_waves={wind_mps = 5.5, fetch_m = 3000.0} (the basin's chop at Boston's mean wind)",
    ),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
) -> None:
    """The field study's findings beside the bench's measurements on the charles_river route, each with a verdict:
    report.md, report.html, plots/ and study.json (exit 1 if the study fails part-way, 130/143 on Ctrl-C/SIGTERM:
    nothing written). With --scenario FILE your own command components (any language: e.g. kiss_icp_pipeline on the
    stretch's rosbag2 recording) are scored beside the built-ins, each with its own verdicts."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from scenarios.study.components import from_scenario, parse_findings
    from scenarios.study.plan import MATCHERS, StudyPlan, parse_stretch
    from scenarios.study.setups import FIELD_METHOD1_ID, parse_setup
    from scenarios.study.study import default_out_dir, run_study

    bar = Progress(
        TextColumn("[bold]study[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        console=console,
        disable=quiet,
    )
    task = bar.add_task("", total=None)

    def progress(done: int, total: int, what: str) -> None:
        bar.update(task, completed=done, total=total, description=f"{what} done")

    with stoppable("study interrupted; nothing written"), user_errors():
        stretch_m = parse_stretch(stretch) if stretch is not None else None
        setups = parse_setup(setup)
        keys = parse_findings(findings_) if findings_ is not None else None
        if keys is not None and scenario_file is None:
            raise ValueError("--findings: give --scenario FILE too (it says where your command components are scored)")
        commands = from_scenario(scenario_file, (*MATCHERS, FIELD_METHOD1_ID), keys) if scenario_file is not None else None
        target = out if out is not None else default_out_dir()
        try:
            with bar:
                path, tree = run_study(
                    target,
                    seed=seed,
                    stretch_m=stretch_m,
                    plan=StudyPlan(workers=workers),
                    progress=progress,
                    setups=setups,
                    commands=commands,
                    command_findings=keys,
                    overrides=set_,
                )
        except RuntimeError as exc:
            errors.print(f"[bold red]study failed:[/] {escape(one_line(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None
    if not quiet:
        table = Table(title="the field study's findings on the bench")
        names = list(tree["setups"])
        for column in ("finding", *(f"verdict ({name})" for name in names), f"the bench ({names[0]})"):
            table.add_column(column)
        for key, f in tree["findings"].items():
            table.add_row(f"{key}. {f['title']}", *(f["setups"][name]["verdict"] for name in names), f["headline"])
            for cid, by_setup in f.get("components", {}).items():
                first = next(iter(by_setup.values()))
                row = (by_setup[name]["verdict"] if name in by_setup else "" for name in names)
                table.add_row(f"   {cid} (command)", *row, first["headline"])
        console.print(table)
    console.print(f"wrote {path / 'report.html'}", highlight=False)


@app.command()
def export(
    source: str = typer.Argument(..., help="library name, .toml path or run directory (its scenario.toml)"),
    format_: str = typer.Option(..., "--format", help="rosbag2, mcap, kitti, pcd, ply or pcap"),
    out: Path = typer.Option(..., help="output directory (rosbag2, mcap, kitti, pcd, ply) or file (pcap)"),
    set_: list[str] = typer.Option([], "--set", help="override a field: key=value (TOML value), repeatable"),
    seed: int = typer.Option(None, help="the scenario's seed"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
) -> None:
    """Simulate a scenario's sensor stream and write it in a format other tools read (nothing is written unless complete)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from scenarios import export as exporting

    bar = Progress(
        TextColumn(f"[bold]export {format_}[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("scans"),
        TimeElapsedColumn(),
        TextColumn("eta"),
        TimeRemainingColumn(),
        console=console,
        disable=quiet,
    )
    task = bar.add_task("export", total=None)

    def progress(done: int, total: int) -> None:
        """Show the bar from the first scan on (bad input ends before it, in one line)."""
        if not bar.live.is_started:
            bar.start()
        bar.update(task, completed=done, total=total)

    with stoppable("export interrupted; nothing written"), user_errors():
        try:
            result = exporting.export(source, format_, out, set=set_, seed=seed, progress=progress)
        finally:
            if bar.live.is_started:
                bar.stop()
    counts = ", ".join(f"{v:,} {k}" for k, v in result.counts.items())
    console.print(
        f"wrote {result.out}: {result.scans} scans{', ' + counts if counts else ''} in {result.seconds:.1f} s "
        f"({result.scans / max(result.seconds, 1e-9):.0f} scans/s)",
        highlight=False,
    )


@app.command()
def replay(
    recording: Path = typer.Argument(
        ..., help="a rosbag2 bag (sqlite3 or MCAP; a ROS 1 .bag too), a Velodyne pcap (HDL-32E, VLP-16, VLP-32C...), or an NMEA log"
    ),
    scenario: str = typer.Option(..., help="the scenario whose matchers, estimators, mount and world origin to use (name or .toml)"),
    set_: list[str] = typer.Option([], "--set", help="override a field of the scenario: key=value (TOML value), repeatable"),
    out: Path = typer.Option(None, help="run directory (default runs/replay-<name>-<UTC time>/)"),
    lidar_topic: str = typer.Option(None, help="the PointCloud2 topic (default: the only one)"),
    gps_topic: str = typer.Option(None, help="the NMEA Sentence or NavSatFix topic (default: the only one)"),
    imu_topic: str = typer.Option(None, help="the sensor_msgs/Imu topic, read when an estimator is fed the IMU (default: the only one)"),
    nmea: Path = typer.Option(None, help="an NMEA log whose fixes replace the recording's own GPS (a capture's GPRMC, a bag's GPS topic)"),
    reference: Path = typer.Option(
        None, help="score the estimators against this reference: a TUM file, an RTK receiver's NMEA log (quality 4/5 fixes) or a GPX track"
    ),
    workers: int = typer.Option(1, min=1, help="processes: 2 overlaps matching with reading"),
    no_report: bool = typer.Option(False, "--no-report", help="skip report.md and report.html"),
    quiet: bool = typer.Option(False, "--quiet", help="no progress bar"),
    view: bool = typer.Option(False, "--view", help="stream the replay to the rerun viewer as it happens (running, else spawned); riverbench[view]"),
    view_save: Path = typer.Option(None, "--view-save", help="write the live view to this .rrd file (open: rerun FILE); riverbench[view]"),
    view_colour: str = typer.Option("height", "--view-colour", help="colour the viewed scan by height or intensity"),
) -> None:
    """Run a scenario's matchers and estimators over a real recording (no truth): a run directory and a report."""
    from scenarios import load as load_scenario
    from scenarios.pipeline.progress import RunProgress
    from scenarios.pipeline.runner import RunFailed, RunInterrupted
    from scenarios.replay import replay as replay_recording
    from scenarios.replay.run import default_out_dir

    with stoppable("replay interrupted; nothing written", (RunInterrupted,)):
        with user_errors():
            if not recording.exists():
                raise ValueError(f"{recording}: no such bag, pcap or NMEA log")
            scenarios_spec = load_scenario(scenario, set=set_)
            observer = None
            if view or view_save is not None:
                out = out if out is not None else default_out_dir(recording)
                observer = _live_view(view, view_save, view_colour, out, "replay")
        try:
            with user_errors(), RunProgress(recording.name, console, quiet) as progress:
                result = replay_recording(
                    recording,
                    scenarios_spec,
                    out,
                    lidar_topic=lidar_topic,
                    gps_topic=gps_topic,
                    imu_topic=imu_topic,
                    nmea=nmea,
                    reference=reference,
                    workers=workers,
                    report=not no_report,
                    progress=progress.update,
                    observer=observer,
                )
        except RunFailed as exc:
            errors.print(f"[bold red]replay failed:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None
    target = result.report if result.report.exists() else result.out_dir
    run = result.metrics["run"]
    if "nmea" in run["recording"]:
        console.print(f"NMEA: {run['recording']['nmea']['summary']}", highlight=False)
    for warning in run.get("warnings", []):
        errors.print(f"[bold yellow]warning:[/] {escape(warning)}", highlight=False, soft_wrap=True)
    what = f"{run['fixes']} fixes (GNSS-only: no LiDAR, estimators without a matcher)" if run["gnss_only"] else f"{run['scans']} scans"
    console.print(f"replayed {what}: {target}", highlight=False)


@app.command()
def score(
    run_dir: Path = typer.Argument(..., help="a finished run directory (what `riverbench run` writes)"),
    component: str = typer.Argument(..., help="NAME=FILE: the component's id in the run and its trajectory file"),
    format_: str = typer.Option("tum", "--format", help="tum ('t tx ty tz qx qy qz qw' lines) or kitti (3x4 row-major poses; stamps in --times)"),
    times: Path = typer.Option(None, "--times", help="kitti: the file of one stamp per pose line (a KITTI times.txt)"),
    frame: str = typer.Option("base_link", help="whose poses: base_link (the vessel's) or lidar (moved to base_link by the run's mount)"),
    clock: str = typer.Option(
        "unix",
        help="the stamps' clock: unix (UNIX time, as ROS and the run's TUM files), run (seconds on the run's clock, as its CSV "
        "files) or first_scan (seconds since the run's first scan, as a KITTI times.txt)",
    ),
    anchor: str = typer.Option(
        "map",
        help="map: poses in the run's map frame, scored as an estimator; first: odometry from its first pose, laid onto the "
        "truth there; se2 / se3: odometry aligned to the truth by the best rigid planar / 3-D motion (evo's -a); "
        "first, se2 and se3 are scored as a matcher",
    ),
    replace: bool = typer.Option(False, "--replace", help="score again a component scored in before under NAME (never a built-in one)"),
    no_report: bool = typer.Option(False, "--no-report", help="leave report.md, report.html and plots/ as they are"),
    quiet: bool = typer.Option(False, "--quiet", help="only the verdict line"),
) -> None:
    """Score a trajectory made outside the bench (KISS-ICP's kiss_icp_pipeline, a ROS or C++ stack run on an export) into a
    finished run directory, as if its component had run inside: APE, RPE, yaw, an estimator's GPS-degradation windows,
    coverage (the share of scans with a pose), the scenario's expectations and goals again; metrics.json, NAME.tum,
    windows.csv and the report are rewritten. Bad input is one line and exit 2 with nothing written; exit 1 when an
    expectation fails.

    \b
    KISS-ICP on an export of the run (docs/guide.md, Scoring a trajectory made elsewhere):
      riverbench export runs/canal --format rosbag2 --out runs/canal_bag
      kiss_icp_pipeline runs/canal_bag
      riverbench score runs/canal kiss=results/latest/canal_bag_poses_tum.txt --frame lidar --anchor first"""
    from scenarios.pipeline.rescore import score as score_in
    from scenarios.score.external import Contract

    with stoppable(f"score interrupted; {run_dir} left as it was"), user_errors():
        name, sep, file = component.partition("=")
        if not sep or not name or not file:
            raise ValueError(f"{component!r}: give NAME=FILE, e.g. kiss=results/poses_tum.txt")
        contract = Contract.parse(format=format_, times=times, frame=frame, clock=clock, anchor=anchor)
        scored = score_in(run_dir, name, Path(file), contract, replace=replace, report=not no_report)
    node = scored.node
    if not quiet:
        what = "an estimator (anchor map)" if scored.section == "estimators" else f"a matcher (anchor {anchor})"
        ape = node["ape"]["rmse"]
        aligned = f", APE aligned rmse {node['ape_aligned']['rmse']} m" if "ape_aligned" in node else ""
        console.print(
            f"scored {name} as {what}: coverage {node['coverage']} of the run's scans, "
            f"APE rmse {ape} m{aligned}, RPE 10 m mean {node['rpe_10m']['mean']} m, yaw p95 {node['yaw']['p95']} deg",
            highlight=False,
            markup=False,
            soft_wrap=True,
        )
    target = scored.run_dir / "report.html"
    console.print(f"{'all expectations pass' if scored.passed else '[bold red]expectations failed[/]'}: {escape(str(target))}", highlight=False)
    raise typer.Exit(0 if scored.passed else 1)


@scenarios_app.command("list")
def scenarios_list(quiet: bool = typer.Option(False, "--quiet", help="the names only, one a line")) -> None:
    """Names and one-line descriptions of the library's scenarios."""
    import scenarios
    from scenarios.spec.library import read

    if quiet:
        for name in scenarios.available():
            console.print(name, highlight=False, markup=False)
        return
    table = Table(title="scenario library")
    table.add_column("name", no_wrap=True)
    table.add_column("description")
    for name in scenarios.available():
        table.add_row(name, escape(str(read(name).get("description", ""))))
    console.print(table)


@scenarios_app.command("show")
def scenarios_show(
    name: str = typer.Argument(..., help="library name or .toml path"),
    set_: list[str] = typer.Option([], "--set", help="override a field: key=value"),
    quiet: bool = typer.Option(False, "--quiet", help="the TOML only, without the heading comment"),
) -> None:
    """The scenario's description, then the resolved scenario (every default filled in) as TOML: what `run` would run."""
    import tomli_w

    import scenarios

    with user_errors():
        spec = scenarios.load(name, set=set_)
    if not quiet:
        console.print(f"# {spec.name}: {spec.description or '(no description)'}", highlight=False, markup=False, soft_wrap=True)
        console.print(f"# resolved, hash {spec.hash}", highlight=False, markup=False)
    console.print(tomli_w.dumps(spec.resolved()), highlight=False, markup=False, soft_wrap=True)


@app.command()
def schema(quiet: bool = typer.Option(False, "--quiet", help="the schema only (what it prints anyway)")) -> None:
    """The JSON Schema of a scenario file (for editors and validators)."""
    import json

    from scenarios.spec.schema import scenario_json_schema

    print(json.dumps(scenario_json_schema(), indent=2))


if __name__ == "__main__":
    app()
