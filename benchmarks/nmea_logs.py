"""Real receivers' NMEA logs (tests/data/nmea, see its NOTICE.md) through the parser, the cn0 monitor and a GNSS-only replay.

Per log, one table row:
- sentences: those pynmea2 reads (strictly with a checksum; without one where NMEA 0183 allows it; of the types sim.nmea.read
  reads), those we read, and
  those both read with every field pynmea2 gives alike (tests/test_nmea_real.py's comparison);
- epochs: fix times in the file (distinct times of the GGA, RMC and GNS pynmea2 reads; a receiver without a fix may
  leave them empty) against the epochs we read and those with a fix;
- cn0 acceptance (share of measured fixes trusted, how many it judged in brackets), before (`per_signal` false: one
  template for every constellation and signal, as before issue 22) and after (per-signal expectations), both online (as
  an estimator feeds it: learning while it judges) and learned from the log first (calibrate() over every fix, then
  check() each: the recording's own epochs as its template);
- the exit code of `riverbench replay LOG --scenario S --quiet --no-report` (a GNSS-only replay; 2: no usable epoch).

    .venv/bin/python benchmarks/nmea_logs.py [--scenario canal_multipath] [--no-replay]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from test_nmea_real import compare, lines_of, pynmea2_reads  # noqa: E402  (the test's comparison is the definition of agreement)

from fusion import monitors  # noqa: E402
from fusion.observation import screen  # noqa: E402
from scenarios.replay import nmea_log  # noqa: E402
from scenarios.replay.recording import Geo, LogStats  # noqa: E402
from sim.nmea import systems  # noqa: E402
from sim.nmea.read import Skipped, kind, read  # noqa: E402

DATA = ROOT / "tests" / "data" / "nmea"
UERE_M = 4.0


def sentences(path: Path) -> tuple[int, int, int, int]:
    """(pynmea2 reads, we read, both read and agree, distinct fix times in the file by pynmea2's reading)."""
    theirs = ours = agree = 0
    times: set[float] = set()
    for line in lines_of(path):
        if not line or line.startswith("#"):
            continue
        msg = pynmea2_reads(line)
        try:
            rec = read(line)
        except Skipped:
            rec = None
        theirs += msg is not None
        ours += rec is not None
        if msg is not None and rec is not None and type(msg).__name__ == kind(rec) and not compare(msg, rec):
            agree += 1
        t = msg.timestamp if msg is not None and type(msg).__name__ in ("GGA", "RMC", "GNS") else None
        if hasattr(t, "hour"):
            times.add(round(t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6, 3))
    return theirs, ours, agree, len(times)


def observations(path: Path) -> tuple[list, LogStats, set[str]]:
    """The log's fixes as estimators screen them (measured only), its counts, and the systems it reports."""
    epoch_utc = datetime(2024, 6, 15, 14, tzinfo=UTC)
    stats = LogStats()
    try:
        first, _, position, _ = nmea_log.span(path, epoch_utc.date(), 0.0)
    except ValueError:
        for _ in nmea_log.stamped(path, epoch_utc.date(), stats):
            pass
        return [], stats, set()
    geo = Geo.choose(nmea_log.Place((0.0, 0.0, 0.0), epoch_utc), first, position)
    out, seen = [], set()
    for event in nmea_log.fix_events(path, geo, epoch_utc.date(), stats):
        seen |= {s.system for s in event.fix.sats}
        obs, _ = screen(event.fix, UERE_M, False)
        if obs is not None:
            out.append(obs)
    return out, stats, seen


def acceptance(obs: list, per_signal: bool, learned_first: bool) -> tuple[float, int]:
    """(share trusted, judged) of the fixes under a fresh cn0 monitor."""
    mon = monitors.create("cn0", per_signal=per_signal)
    if learned_first:
        for o in obs:
            mon.calibrate(o)
    trusted = judged = 0
    for o in obs:
        verdict = mon.check(o, None)
        if not learned_first:
            mon.commit(o, verdict)
        trusted += verdict.trusted
        judged += math.isfinite(verdict.statistic)
    return (trusted / len(obs) if obs else math.nan), judged


def replay_exit(path: Path, scenario: str) -> int:
    """Exit code of a GNSS-only replay of the log through the CLI."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "scenarios.cli", "replay", str(path), "--scenario", scenario, "--out", f"{tmp}/run", "--quiet", "--no-report"]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=600).returncode


def share(value: float, judged: int) -> str:
    return "–" if value != value else f"{100 * value:.0f} % ({judged})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="canal_multipath", help="scenario of the GNSS-only replays [canal_multipath]")
    parser.add_argument("--no-replay", action="store_true", help="skip the replays (their exit codes)")
    args = parser.parse_args()
    print(
        "| log | systems | pynmea2 reads | we read | agree | fix times in file | epochs read | with a fix "
        "| cn0 online before | after | cn0 learned before | after | replay exit |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    totals = [0, 0, 0]
    for path in sorted(DATA.rglob("*.log")):
        theirs, ours, agree, in_file = sentences(path)
        totals = [a + b for a, b in zip(totals, (theirs, ours, agree))]
        obs, stats, seen = observations(path)
        cells = [share(*acceptance(obs, per_signal, learned)) for learned in (False, True) for per_signal in (False, True)]
        code = "" if args.no_replay else str(replay_exit(path, args.scenario))
        named = ", ".join(sorted(seen - {systems.UNKNOWN})) or "–"
        print(
            f"| {path.name} | {named} | {theirs} | {ours} | {agree} | {in_file} | {stats.epochs} | {stats.with_fix} | {' | '.join(cells)} | {code} |"
        )
    print(f"\nall logs: pynmea2 reads {totals[0]} sentences, we read {totals[1]}, {totals[2]} alike")


if __name__ == "__main__":
    main()
