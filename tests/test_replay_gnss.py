"""GNSS-only replays of real receivers' NMEA (tests/data/nmea, see its NOTICE.md) and scoring against a reference.

nmea_navsat_driver's RTK log (120 epochs at 2 Hz, GGA quality 4) is its own reference: a copy degraded by a known
offset, as an autonomous receiver (quality 1), with a 5 s blackout, must score exactly that offset; GPX and TUM
references built from it likewise. Bags with NMEA sentences or NavSatFix and no point cloud are GNSS-only too; bad
files are one line, exit 2, nothing written."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pymap3d
import pynmea2
import pytest
from rosbags.rosbag2 import Writer

import scenarios
from scenarios.export.ros_messages import header, typestore
from scenarios.pipeline import files
from scenarios.replay import nmea_log, replay
from scenarios.report.plots import read_csv
from sim.nmea import checksum
from sim.nmea.epochs import Tally

DATA = Path(__file__).parent / "data" / "nmea"
RTK = DATA / "nmea_navsat_driver_rtk_nmea.log"
SCENARIO = "canal_multipath"
SHIFT_DEG = (2e-5, 3e-5)  # north, east
BLACKOUT = range(40, 50)  # epochs without a fix: 5 s


def sentence(body: str) -> str:
    return f"${body}*{checksum(body)}"


def shifted(value: str, hemisphere: str, degrees: float) -> str:
    """A (d)ddmm.mmmmmmm field moved by `degrees` (north or east), printed with its own decimals."""
    whole, minutes = divmod(float(value), 100.0)
    total = whole + minutes / 60.0 + degrees * (1 if hemisphere in "NE" else -1)
    d = int(total)
    return f"{d:0{len(value.split('.')[0]) - 2}d}{(total - d) * 60:0{len(value) - len(value.split('.')[0]) + 2}.{len(value.split('.')[1])}f}"


def degrade(src: Path, dst: Path) -> None:
    """The RTK log as an autonomous receiver SHIFT_DEG off would write it, with no fix in the BLACKOUT epochs."""
    out = []
    for k, line in enumerate(src.read_text().splitlines()):
        f = line[1:].split("*")[0].split(",")
        epoch = k // 2
        if f[0].endswith("GGA"):
            if epoch in BLACKOUT:
                f[2:6], f[6], f[7], f[8] = ["", "", "", ""], "0", "00", ""
            else:
                f[2], f[4], f[6] = shifted(f[2], f[3], SHIFT_DEG[0]), shifted(f[4], f[5], SHIFT_DEG[1]), "1"
        else:
            if epoch in BLACKOUT:
                f[2], f[3:7], f[12] = "V", ["", "", "", ""], "N"
            else:
                f[3], f[5], f[12] = shifted(f[3], f[4], SHIFT_DEG[0]), shifted(f[5], f[6], SHIFT_DEG[1]), "A"
        out.append(sentence(",".join(f)))
    dst.write_text("\r\n".join(out) + "\r\n")


def expected_offset_m() -> float:
    """Horizontal distance of SHIFT_DEG at the log's place."""
    lat, lon = 48.7733, 8.9121
    e, n, _ = pymap3d.geodetic2enu(lat + SHIFT_DEG[0], lon + SHIFT_DEG[1], 0.0, lat, lon, 0.0)
    return math.hypot(e, n)


@pytest.fixture(scope="module")
def degraded(tmp_path_factory):
    root = tmp_path_factory.mktemp("gnss")
    degrade(RTK, root / "degraded.nmea")
    return root, replay(root / "degraded.nmea", SCENARIO, root / "run", reference=RTK, report=True)


def test_a_degraded_copy_scores_its_offset_against_the_rtk_log(degraded):
    root, result = degraded
    m = result.metrics
    assert m["run"]["gnss_only"] and m["run"]["scans"] == 0 and m["run"]["fixes"] == 120 and m["run"]["pose_samples"] == 120
    assert m["run"]["recording"]["nmea"]["epochs"] == 120 and m["run"]["recording"]["nmea"]["with_fix"] == 110
    assert m["reference"]["format"] == "RTK NMEA" and m["reference"]["samples"] == 120 and m["reference"]["point"] == "antenna"
    node = m["estimators"]["gps_only"]["against_reference"]
    want = expected_offset_m()
    assert node["scored"] == 120 and node["available"] == 1.0
    # the receiver prints 7 decimals of minutes (0.2 mm); the static antenna moves a few mm between RTK epochs
    assert abs(node["ape"]["median"] - want) < 0.005 and node["ape"]["max"] < want + 0.02
    blackout = node["blackout"]
    assert blackout["count"] == 1 and blackout["seconds"] == pytest.approx(5.0)
    assert abs(blackout["max_error"] - want) < 0.02  # gps_only holds its last fix through the blackout
    assert set(m["estimators"]) == {"gps_only", "hdop_switch", "ekf", "pf"} and not m["matchers"]
    assert files.read_tum(result.out_dir / "gicp.tum").shape == (0, 8)  # no matcher ran: its file is its header, as a run's
    report = (result.out_dir / "report.md").read_text().splitlines()
    assert report[2].startswith("Scored against the reference nmea_navsat_driver_rtk_nmea.log (RTK NMEA")
    assert report[4].startswith("GNSS-only replay: the recording has no LiDAR")
    assert "## Estimators against the reference" in report


def test_without_a_reference_the_first_line_says_it_is_agreement_with_gps(degraded, tmp_path):
    root, _ = degraded
    result = replay(root / "degraded.nmea", SCENARIO, tmp_path / "run", report=True)
    first = (result.out_dir / "report.md").read_text().splitlines()[2]
    assert "agreement with GPS, not accuracy" in first and "reference" not in result.metrics


def test_gpx_and_tum_references(degraded, tmp_path):
    root, result = degraded
    # GPX of the RTK log's own positions: the log replayed against it is 0 off
    points = []
    for ns, epoch in nmea_log.stamped(RTK, datetime(2020, 1, 1).date(), nmea_log.LogStats()):
        when = datetime.fromtimestamp(ns / 1e9, UTC).isoformat().replace("+00:00", "Z")
        points.append(f'<trkpt lat="{epoch.lat:.10f}" lon="{epoch.lon:.10f}"><ele>{epoch.alt:.3f}</ele><time>{when}</time></trkpt>')
    gpx = tmp_path / "track.gpx"
    gpx.write_text(
        '<?xml version="1.0"?><gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1"><trk><trkseg>'
        + "".join(points)
        + "</trkseg></trk></gpx>"
    )
    own = replay(RTK, SCENARIO, tmp_path / "own", reference=gpx, report=False)
    node = own.metrics["estimators"]["gps_only"]["against_reference"]
    assert own.metrics["reference"]["format"] == "GPX" and node["scored"] == 120 and node["ape"]["max"] < 1e-3
    # TUM (UNIX time, base_link in the replay's frame): the degraded replay's own gps_only track, 1 m further east
    rows = files.read_tum(result.out_dir / "gps_only.tum")  # already UNIX time, as every TUM file riverbench writes
    rows[:, 1] += 1.0
    tum = tmp_path / "ref.tum"
    np.savetxt(tum, rows, fmt="%.9f")
    scored = replay(root / "degraded.nmea", SCENARIO, tmp_path / "tum", reference=tum, report=False)
    node = scored.metrics["estimators"]["gps_only"]["against_reference"]
    assert scored.metrics["reference"]["format"] == "TUM" and node["ape"]["max"] == pytest.approx(1.0, abs=1e-5)


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "scenarios.cli", "replay", *args], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_a_reference_that_does_not_overlap_is_one_line_and_exit_2(degraded, tmp_path):
    root, _ = degraded
    next_day = [
        line if "RMC" not in line else sentence(line[1:].split("*")[0].replace(",200420,", ",210420,")) for line in RTK.read_text().splitlines()
    ]
    (tmp_path / "next_day.nmea").write_text("\n".join(next_day) + "\n")
    with pytest.raises(ValueError, match="do not overlap") as error:
        replay(root / "degraded.nmea", SCENARIO, tmp_path / "out", reference=tmp_path / "next_day.nmea")
    assert "\n" not in str(error.value) and not (tmp_path / "out").exists()
    bad = cli(str(root / "degraded.nmea"), "--scenario", SCENARIO, "--out", "out", "--reference", "next_day.nmea", "--quiet", cwd=tmp_path)
    assert bad.returncode == 2 and "do not overlap" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_garbage_and_truncated_lines_are_counted_and_a_file_without_a_fix_is_exit_2(tmp_path):
    lines = RTK.read_text().splitlines()
    noisy = lines[:10] + ["garbage \x00\x01 line", lines[10][:30], lines[11][:-2] + "00", "$PUBX,00,proprietary*00", "!AIVDM,1,1,,A,x,0*00"]
    noisy += lines[12:] + [lines[0][:20]]
    (tmp_path / "noisy.nmea").write_bytes("\r\n".join(noisy).encode("latin-1") + b"\r\n\xff\xfe")
    result = replay(tmp_path / "noisy.nmea", SCENARIO, tmp_path / "run", report=False)
    nmea = result.metrics["run"]["recording"]["nmea"]
    # a proprietary sentence's checksum is checked first: $PUBX here is a bad checksum
    assert nmea["skipped"] == {"no checksum": 2, "not a sentence": 2, "bad checksum": 2, "other type": 1}
    assert nmea["read"] == {"GGA": 119, "RMC": 119} and nmea["epochs"] == 119
    (tmp_path / "junk.nmea").write_text("\n".join(["garbage", lines[0][:30], "$GPGGA,,,,,,0,00,,,,,,,*66"]) + "\n")
    ok = cli("noisy.nmea", "--scenario", SCENARIO, "--out", "cli", "--quiet", "--no-report", cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "NMEA: read 238 sentences" in ok.stdout and "skipped 7 lines" in ok.stdout and "replayed 119 fixes (GNSS-only" in ok.stdout
    bad = cli("junk.nmea", "--scenario", SCENARIO, "--out", "junk", "--quiet", cwd=tmp_path)
    assert bad.returncode == 2 and "no usable NMEA epoch" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "junk").exists()


def bag_of(path: Path, topic: str, msgtype: str, messages: list[tuple[int, object]]) -> None:
    store = typestore()
    with Writer(path, version=8) as writer:
        connection = writer.add_connection(topic, msgtype, typestore=store)
        for ns, msg in messages:
            writer.write(connection, ns, store.serialize_cdr(msg, msgtype))


def test_bags_of_nmea_sentences_or_navsatfix_alone_are_gnss_only(tmp_path):
    store = typestore()
    log = replay(RTK, SCENARIO, tmp_path / "log", report=False)
    stamped = list(nmea_log.stamped(RTK, datetime(2020, 1, 1).date(), nmea_log.LogStats()))
    sentences = [(ns, line) for ns, epoch in stamped for line in epoch.lines]
    msg = store.types["nmea_msgs/msg/Sentence"]
    bag_of(
        tmp_path / "nmea_bag",
        "/nmea_sentence",
        "nmea_msgs/msg/Sentence",
        [(ns, msg(header=header(store, ns, "gps"), sentence=s)) for ns, s in sentences],
    )
    from_bag = replay(tmp_path / "nmea_bag", SCENARIO, tmp_path / "bag_run", report=False)
    assert from_bag.metrics["run"]["gnss_only"] and from_bag.metrics["run"]["recording"]["nmea"]["epochs"] == 120
    a, b = read_csv(log.out_dir / "gps.csv"), read_csv(from_bag.out_dir / "gps.csv")
    for column in ("t", "quality", "hdop", "num_sats"):
        np.testing.assert_array_equal(a[column], b[column], err_msg=column)
    # the same ENU frame but for its origin's height: the bag's is its first sentence's (an RMC: the world's), the log's its first fix's
    np.testing.assert_allclose(np.c_[a["e"], a["n"], a["u"] - a["u"][0]], np.c_[b["e"], b["n"], b["u"] - b["u"][0]], atol=1e-3)
    navsat = store.types["sensor_msgs/msg/NavSatFix"]
    status = store.types["sensor_msgs/msg/NavSatStatus"]
    fixes = [
        (
            ns,
            navsat(
                header=header(store, ns, "gps"),
                status=status(status=2, service=1),
                latitude=e.lat,
                longitude=e.lon,
                altitude=e.alt,
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            ),
        )
        for ns, e in stamped
    ]
    bag_of(tmp_path / "navsat_bag", "/fix", "sensor_msgs/msg/NavSatFix", fixes)
    from_navsat = replay(tmp_path / "navsat_bag", SCENARIO, tmp_path / "navsat_run", report=False)
    assert from_navsat.metrics["run"]["gnss_only"] and from_navsat.metrics["run"]["fixes"] == 120
    assert "nmea" not in from_navsat.metrics["run"]["recording"]
    track = files.read_tum(from_navsat.out_dir / "gps_only.tum")
    np.testing.assert_allclose(track[:, 1:3], files.read_tum(log.out_dir / "gps_only.tum")[:, 1:3], atol=0.002)


def test_tally_summary_names_every_reason():
    tally = Tally()
    tally.read["GGA"] += 2
    tally.skipped["bad checksum"] += 1
    assert tally.summary() == "read 2 sentences (GGA 2); skipped 1 lines (1 bad checksum)"


def test_a_log_without_checksums_replays_with_pynmea2s_fixes(tmp_path):
    """gpsd's hp58534a.log writes no checksum (NMEA 0183 allows it): it replays (exit 0), its fixes are pynmea2's."""
    log = DATA / "gpsd" / "hp58534a.log"
    done = cli(str(log), "--scenario", SCENARIO, "--out", "run", "--quiet", "--no-report", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    said = " ".join(done.stdout.split())  # rich wraps at the terminal width
    assert "11 of them without a checksum" in said and "replayed 2 fixes" in said
    theirs = [pynmea2.parse(line) for line in log.read_text().splitlines() if line.startswith("$GPGGA")]
    fixes = read_csv(tmp_path / "run" / "gps.csv")  # degrees to 9 decimals
    assert list(zip(fixes["lat"], fixes["lon"])) == [pytest.approx((m.latitude, m.longitude), abs=1e-9) for m in theirs]
    recording = json.loads((tmp_path / "run" / "metrics.json").read_text())["run"]["recording"]["nmea"]
    assert recording["read_without_checksum"] == 11


def test_the_clock_is_built_from_valid_fixes_only(tmp_path):
    """mtk-3301.log's receiver reports 1980 dates until its first fix in 2008: those epochs are set aside and counted, and
    the replay spans the log's real seconds; an epoch whose date jumps a day or more (a reset receiver) is set aside too."""
    result = replay(DATA / "gpsd" / "mtk-3301.log", SCENARIO, tmp_path / "mtk", report=False)
    nmea = result.metrics["run"]["recording"]["nmea"]
    assert nmea["before_first_fix"] == 7 and nmea["with_fix"] == 4 and nmea["clock_jumps"] == 0
    assert result.metrics["run"]["duration_s"] == pytest.approx(3.0)
    stamps = [ns for ns, _ in nmea_log.stamped(DATA / "gpsd" / "mtk-3301.log", datetime(2020, 1, 1).date(), nmea_log.LogStats())]
    assert datetime.fromtimestamp(stamps[0] / 1e9, UTC).date() == datetime(2008, 8, 23).date()
    lines = RTK.read_text().splitlines()
    reset = [line.replace(",200420,", ",060180,") for line in lines[40:42]]  # one epoch's RMC dated the GPS epoch's week
    reset = [line.split("*")[0] + "*" + checksum(line.split("*")[0][1:]) for line in reset]
    (tmp_path / "reset.nmea").write_text("\n".join(lines[:40] + reset + lines[42:]) + "\n")
    stats = nmea_log.LogStats()
    kept = list(nmea_log.stamped(tmp_path / "reset.nmea", datetime(2020, 1, 1).date(), stats))
    assert stats.clock_jumps == 1 and len(kept) == 119 and (kept[-1][0] - kept[0][0]) / 1e9 == pytest.approx(59.5)


def test_estimators_start_on_a_static_log_position_first(tmp_path):
    """nmea_navsat_driver's RTK log is a receiver at rest (RMC speed 0.01 kn): ekf, pf and hdop_switch start on its
    position within its first fixes, their heading unknown (no motion, compass or course gives one), and give tracks over
    at least 95% of its fixes' span; the report says what gave each heading."""
    result = replay(RTK, SCENARIO, tmp_path / "run", report=True)
    span = result.metrics["run"]["duration_s"]
    for eid in ("ekf", "pf", "hdop_switch"):
        track = files.read_tum(tmp_path / "run" / f"{eid}.tum", scenario_time=True)
        assert (track[-1, 0] - track[0, 0]) / span >= 0.95
        assert result.metrics["estimators"][eid]["startup"]["heading_from"] == "unknown (at rest: position only)"
        assert np.hypot(*(track[:, 1:3] - track[0, 1:3]).T).max() < 0.5  # it stays where the vessel lies
    assert "heading by" in (tmp_path / "run" / "report.md").read_text()
    # every component has its file, as a run writes them: the matcher that did not run (no LiDAR) its header only
    spec = scenarios.load(SCENARIO)
    assert {f"{c.id}.tum" for c in [*spec.matchers, *spec.estimators]} == {p.name for p in (tmp_path / "run").glob("*.tum")}
    assert all(files.read_tum(tmp_path / "run" / f"{m.id}.tum").shape == (0, 8) for m in spec.matchers)
