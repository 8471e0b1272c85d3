"""The recording cache (scenarios.pipeline.recording_cache) under concurrency: two processes after one key, as two sweep
workers at one seed are, write the recording once; the second waits for the first and reads what it wrote."""

import multiprocessing
from pathlib import Path

import scenarios
from scenarios.pipeline import recording_cache

ONE_SECOND = ["stretch={start_s = 0.0, end_s = 1.0}", "expect=[]", "goals=[]"]
"""open_river's first second: an NMEA recording of it takes about a second to write."""


def _get(root: str, start, results) -> None:
    """A worker: wait for the other, then ask the cache for the recording; report whether it had it."""
    scenario = scenarios.load("open_river", set=ONE_SECOND)
    start.wait()
    got = recording_cache.get(scenario, "nmea", Path(root))
    results.put((got.hit, str(got.path), got.path.read_bytes()))


def test_two_processes_after_one_key_write_it_once(tmp_path):
    context = multiprocessing.get_context("fork")
    start, results = context.Barrier(2), context.Queue()
    workers = [context.Process(target=_get, args=(str(tmp_path), start, results)) for _ in range(2)]
    for worker in workers:
        worker.start()
    got = [results.get(timeout=60) for _ in workers]
    for worker in workers:
        worker.join(10)
        assert worker.exitcode == 0
    assert sorted(hit for hit, _, _ in got) == [False, True]  # one wrote, the other waited and read it
    assert got[0][1:] == got[1][1:] and got[0][2].startswith(b"$GNGGA")
    entries = sorted(p.name for p in (tmp_path / "recordings").iterdir())
    key = recording_cache.key(scenarios.load("open_river", set=ONE_SECOND), "nmea")
    assert entries == [key, f"{key}.lock"]  # no hidden temporary left


def test_a_killed_writers_temporary_is_cleared_by_the_next(tmp_path):
    scenario = scenarios.load("open_river", set=ONE_SECOND)
    key = recording_cache.key(scenario, "nmea")
    stale = tmp_path / "recordings" / f".{key}.0123456789ab"
    stale.mkdir(parents=True)
    (stale / "recording.nmea").write_text("half")
    got = recording_cache.get(scenario, "nmea", tmp_path)
    assert not got.hit and not stale.exists() and got.path.read_bytes().startswith(b"$GNGGA")
