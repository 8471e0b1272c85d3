"""How far a physically nothing input change moves a run's metrics, against the spread over seeds the regression check judges by.

Each scenario's [fast] variant runs on one seed as is and changed, and for each estimator's and matcher's headline
metrics the script prints both values, the move, and the move as a share of the range over the seeds stored in the
baseline (`benchmarks/baseline/library.json`). A share near 1 means a change that touches nothing physical can look
like a regression of the whole seed spread, and a real one can hide in that noise. The change is one of:

- (default) one LiDAR return dropped from the revolution nearest the middle of the stretch (its farthest point: one
  drop-out among tens of thousands);
- `--shift S`: event times moved by S seconds as the matchers and estimators see them (the simulation itself runs at
  the unshifted times, as a recording replayed with another clock would): `--events fixes` every fix's stamp,
  `scans` every scan's, `fix` / `scan` the one nearest the middle of the stretch only;
- `--shift S --shifts N`: N runs shifted by S, 2S, ..., NS; per metric the range over those runs (and the run as is)
  beside the seeds' range, so a reader knows what move of a metric is noise.

    .venv/bin/python benchmarks/sensitivity.py [SCENARIO ...] [--seed 0] [--baseline benchmarks/baseline/library.json]
        [--shift 1e-10 [--events fixes|scans|fix|scan] [--shifts N]]
"""

from __future__ import annotations

import argparse
import dataclasses
import heapq
import itertools
import math
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import scenarios
import sim
from scenarios.pipeline import vessel_run
from scenarios.pipeline.stream import FixEvent, ScanEvent
from scenarios.score.baseline import flatten, load
from scenarios.spec.library import load_fast
from sim.scan import Scan

BASELINE = Path(__file__).resolve().parent / "baseline" / "library.json"
METRICS = ("ape.p95", "ape.max", "yaw.p95", "ape_aligned.p95", "ape_aligned.max")
"""Headline metrics of an estimator or matcher (below its id), besides every window kind's max_error."""
EVENTS = ("fixes", "scans", "fix", "scan")


def headline(key: str) -> bool:
    """Whether a dotted metrics path is a headline metric of an estimator or a matcher."""
    if not key.startswith(("estimators.", "matchers.")):
        return False
    rest = key.split(".", 2)[2]
    return rest in METRICS or (rest.startswith("windows.") and rest.endswith(".max_error"))


@contextmanager
def dropped_return(drop_at: float | None) -> Iterator[None]:
    """The revolution starting nearest `drop_at` (None: none) loses its farthest return, within the block."""
    original = sim.HDL32E.scan

    def scan(self, world, trajectory, t0):
        result = original(self, world, trajectory, t0)
        if drop_at is None or abs(t0 - drop_at) > 0.5 / self.config.rate_hz or not len(result.points):
            return result
        p = result.points
        farthest = int(np.argmax(p["x"].astype(float) ** 2 + p["y"].astype(float) ** 2 + p["z"].astype(float) ** 2))
        return Scan(stamp=result.stamp, points=np.delete(p, farthest))

    sim.HDL32E.scan = scan  # the LiDAR runs in this process with workers=1 (the matcher pool gets the scans it produced)
    try:
        yield
    finally:
        sim.HDL32E.scan = original


def shift_event(event, delta: float):
    """The same scan or fix stamped `delta` s later (the data as simulated at the unshifted time)."""
    if isinstance(event, ScanEvent):
        return ScanEvent(event.stamp + delta, Scan(stamp=event.scan.stamp + delta, points=event.scan.points))
    return FixEvent(event.stamp + delta, dataclasses.replace(event.fix, stamp=event.fix.stamp + delta))


def shifted_stream(stream: Iterator, delta: float, chosen: Callable[[object], bool]) -> Iterator:
    """`stream` with the chosen events shifted by `delta`, in time order again (a scan before a fix at equal stamps)."""
    order = itertools.count()
    pending: list[tuple[float, int, int, object]] = []
    for event in stream:
        moved = shift_event(event, delta) if chosen(event) else event
        heapq.heappush(pending, (moved.stamp, 0 if isinstance(moved, ScanEvent) else 1, next(order), moved))
        while pending and pending[0][0] < event.stamp - 2.0 * abs(delta):
            yield heapq.heappop(pending)[3]
    while pending:
        yield heapq.heappop(pending)[3]


def chooser(events: str, middle: float) -> Callable[[object], bool]:
    """Which events a shift moves: every fix or scan, or only the fix or scan nearest `middle` (within half a period)."""
    kind = FixEvent if events.startswith("fix") else ScanEvent
    if events in ("fixes", "scans"):
        return lambda e: isinstance(e, kind)
    half = 0.1 if kind is FixEvent else 0.05  # half the 5 Hz fix and 10 Hz scan periods: exactly one event
    return lambda e: isinstance(e, kind) and middle - half <= e.stamp < middle + half


@contextmanager
def shifted_times(delta: float, chosen: Callable[[object], bool]) -> Iterator[None]:
    """Within the block, open-loop runs feed their matchers and estimators the chosen events shifted by `delta`."""
    original = vessel_run.planned_events

    def events(*args, **kwargs):
        return shifted_stream(original(*args, **kwargs), delta, chosen)

    vessel_run.planned_events = events
    try:
        yield
    finally:
        vessel_run.planned_events = original


def run(name: str, seed: int, out: Path) -> dict[str, float | None]:
    """The flattened metrics of the [fast] run of `name` on `seed` (one process: the patches above apply)."""
    return flatten(scenarios.run(load_fast(name, seed=seed), out, workers=1, report=False).metrics)


def seed_range(stored: dict, name: str, key: str) -> float:
    """max - min of a metric over the baseline's seeds (NaN with fewer than two values)."""
    values = [v for v in (stored[name].metrics if name in stored else {}).get(key, []) if v is not None]
    return max(values) - min(values) if len(values) > 1 else math.nan


def label(key: str) -> str:
    """A metric path without its estimators./matchers. prefix."""
    return key.replace("estimators.", "").replace("matchers.", "")


def middle_of(metrics: dict[str, float | None]) -> float:
    """The middle of a run's stretch."""
    return 0.5 * (float(metrics["run.t_start"] or 0.0) + float(metrics["run.t_end"] or 0.0))


def compare(name: str, args: argparse.Namespace, stored: dict, root: Path) -> None:
    """One table block: the run as is against the run changed once (a dropped return or a shift)."""
    before = run(name, args.seed, root / f"{name}-as-is")
    if args.shift is None:
        with dropped_return(middle_of(before)):
            after = run(name, args.seed, root / f"{name}-dropped")
    else:
        with shifted_times(args.shift, chooser(args.events, middle_of(before))):
            after = run(name, args.seed, root / f"{name}-shifted")
    for key, value in before.items():
        if value is None or not headline(key):
            continue
        spread, moved = seed_range(stored, name, key), after.get(key)
        move = math.nan if moved is None else moved - value
        share = abs(move) / spread if spread > 0 else math.nan
        cells = [name, str(args.seed), label(key), f"{value:.3g}", f"{value + move:.3g}", f"{move:+.3g}", f"{spread:.3g}", f"{share:.2f}"]
        print("| " + " | ".join(cells) + " |", flush=True)


def spread(name: str, args: argparse.Namespace, stored: dict, root: Path) -> None:
    """One table block: the range of each metric over the run as is and N shifted runs, beside the seeds' range."""
    before = run(name, args.seed, root / f"{name}-as-is")
    runs = [before]
    for k in range(1, args.shifts + 1):
        with shifted_times(k * args.shift, chooser(args.events, middle_of(before))):
            runs.append(run(name, args.seed, root / f"{name}-shifted-{k}"))
    for key, value in before.items():
        if value is None or not headline(key):
            continue
        values = [v for v in (r.get(key) for r in runs) if v is not None]
        lo, hi, seeds = min(values), max(values), seed_range(stored, name, key)
        share = (hi - lo) / seeds if seeds > 0 else math.nan
        cells = [name, label(key), f"{value:.3g}", f"{lo:.3g}..{hi:.3g}", f"{hi - lo:.3g}", f"{seeds:.3g}", f"{share:.2f}"]
        print("| " + " | ".join(cells) + " |", flush=True)


def header(args: argparse.Namespace) -> None:
    """The table's header for the mode asked."""
    if args.shift is None:
        changed = "one return dropped"
    else:
        changed = f"{args.events} shifted {args.shift:g} s"
    if args.shift is not None and args.shifts:
        n = args.shifts + 1
        print(
            f"| scenario [fast] | metric | as is | range over {n} runs (as is, {args.events} shifted k x {args.shift:g} s, k = 1..{args.shifts}) "
            "| that range | range over the baseline's seeds | ratio |"
        )
        print("|---|---|---|---|---|---|---|")
        return
    print(f"| scenario [fast] | seed | metric | as is | {changed} | move | range over the baseline's seeds | move / range |")
    print("|---|---|---|---|---|---|---|---|")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=["charles_river", "quickstart", "chase_boat"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--baseline", type=Path, default=BASELINE)
    parser.add_argument("--shift", type=float, default=None, help="move event times by this many seconds instead of dropping a return")
    parser.add_argument("--events", choices=EVENTS, default="fixes", help="which events --shift moves (default: every fix)")
    parser.add_argument("--shifts", type=int, default=0, help="with --shift: N runs shifted by k x SHIFT, k = 1..N, and their range per metric")
    args = parser.parse_args()
    try:
        stored = load(args.baseline).scenarios
        for name in args.scenarios:
            load_fast(name)  # an unknown scenario or one without a [fast] variant: refused before anything runs
        if args.shifts < 0 or (args.shifts and args.shift is None):
            raise ValueError("--shifts needs --shift and is at least 0")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    header(args)
    with tempfile.TemporaryDirectory(prefix="riverbench-sensitivity-") as root:
        for name in args.scenarios:
            (spread if args.shifts else compare)(name, args, stored, Path(root))
    return 0


if __name__ == "__main__":
    sys.exit(main())
