"""Replay of real Velodyne captures (tests/data/pcap: VeloView's HDL-32E and VLP-16, see the NOTICE there) and of
synthetic streams of the other models: the sensor is found from its factory bytes checked against what the packets
show, whole revolutions decode as velodyne_decoder decodes them, partial ones are dropped, the sensor, capture and
GNSS clocks give one timeline with every fix on it, and what cannot be replayed is one line and exit 2."""

from __future__ import annotations

import math
import re
import struct
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import dpkt
import numpy as np
import pynmea2
import pytest
import velodyne_decoder as vd
from velodyne_streams import ranges, stream

import scenarios
from riverbench.unixtime import unix_ns
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import pcap, replay
from scenarios.replay.recording import Place, RecordedFix
from scenarios.replay.velodyne import BY_NAME, MODELS, Evidence, identify
from sim.lidar import HDL32E_ELEVATION_DEG

DATA = Path(__file__).parent / "data" / "pcap"
HDL32E = DATA / "monterey-hdl32e-prefix.pcap"
VLP16 = DATA / "vlp16-0x21-prefix.pcap"
PLACE = Place((42.3539, -71.1106, 5.0), datetime(2024, 6, 15, 14, tzinfo=UTC))  # a Boston world: both captures are far from it


def read(path: Path, place: Place = PLACE):
    """The opened capture and its events (scans and fixes in replay order)."""
    recording = pcap.read(path, place)
    return recording, list(recording.events())


def scans(events) -> list:
    return [e.scan for e in events if isinstance(e, ScanEvent)]


def elevations(points: np.ndarray) -> np.ndarray:
    """Each point's elevation (deg) from its coordinates."""
    return np.degrees(np.arctan2(points["z"].astype(float), np.hypot(points["x"].astype(float), points["y"].astype(float))))


def udp(path: Path) -> list[tuple[int, bytes]]:
    """(capture time ns, UDP payload) of every record, read by dpkt (independently of the reader under test)."""
    with path.open("rb") as handle:
        return [(round(ts * 1e6) * 1000, bytes(dpkt.ethernet.Ethernet(buf).data.data.data)) for ts, buf in dpkt.pcap.Reader(handle)]


def test_an_hdl32e_capture_decodes_as_velodyne_decoder_decodes_it():
    recording, events = read(HDL32E)
    facts = recording.facts
    assert (facts["sensor"], facts["sensor_note"], facts["return_mode"]) == ("HDL-32E", "", "strongest return")
    config = vd.Config(model=vd.Model.HDL32E, calibration=vd.get_bundled_calibration("HDL-32E.yml"), timestamp_first_packet=True)
    config.cut_angle = 180.0  # the scenario's lidar starts its revolutions behind the sensor
    theirs = list(vd.read_pcap(str(HDL32E), config, as_pcl_structs=True))
    ours = scans(events)
    # velodyne_decoder's first scan starts where the capture does (150.5 deg) and its last ends where it does: partial
    assert len(theirs[0].points) < 0.2 * len(theirs[1].points) and len(theirs[-1].points) < 0.9 * len(theirs[1].points)
    assert len(ours) == len(theirs) - 2 == facts["revolutions"] == 7 and facts["partial_revolutions_dropped"] == 2
    model = BY_NAME["HDL-32E"]
    offset = facts["clocks"]["sensor_minus_gnss_s"]
    for scan, (stamp, points) in zip(ours, theirs[1:-1], strict=True):
        # its first packet's sensor time (velodyne_decoder's device stamp) on GNSS time
        assert scan.stamp == pytest.approx(stamp.device - offset - recording.geo.zero_ns / 1e9, abs=2e-6)
        for name in ("x", "y", "z", "intensity"):
            np.testing.assert_array_equal(scan.points[name], points[name], err_msg=name)
        np.testing.assert_allclose(scan.points["time"], points["time"], rtol=0, atol=1e-6)
        np.testing.assert_array_equal(scan.points["ring"], model.laser_of_ring[points["ring"]])
        # laser ids in the simulator's numbering: each point lies on the datasheet's beam of its laser (to 0.01 deg)
        assert np.abs(elevations(scan.points) - HDL32E_ELEVATION_DEG[scan.points["ring"]]).max() < 0.01
        assert 49_000 < len(scan.points) < 50_200
    assert [s.stamp for s in ours] == sorted(s.stamp for s in ours) and np.ptp(np.diff([s.stamp for s in ours])) < 2e-3  # 11.77 Hz


def test_the_hdl32e_captures_clocks_are_measured_and_every_fix_is_on_the_timeline():
    """The sensor's clock (us past the hour), the capture clock and GPRMC disagree: measured here with dpkt and pynmea2."""
    records = udp(HDL32E)
    data = [(ns, int.from_bytes(p[1200:1204], "little")) for ns, p in records if len(p) == 1206]
    hour = datetime(2012, 12, 11, 22, tzinfo=UTC)
    sensor_ns = lambda us: unix_ns(hour) + us * 1000  # the capture's and sensor's hour: 22:00
    capture_minus_sensor = np.median([ns - sensor_ns(us) for ns, us in data]) / 1e9
    positions = [(ns, p) for ns, p in records if len(p) == 512]
    sentences = [p[206:].split(b"\r\n")[0].decode() for _, p in positions]
    arrival = next(i for i, s in enumerate(sentences) if s != sentences[0])  # 22:06:33's sentence first seen
    rmc = pynmea2.parse(sentences[arrival])
    epoch = unix_ns(datetime.combine(rmc.datestamp, rmc.timestamp, tzinfo=UTC))
    sensor_minus_gnss = (sensor_ns(int.from_bytes(positions[arrival][1][198:202], "little")) - epoch) / 1e9
    capture_minus_gnss = (positions[arrival][0] - epoch) / 1e9
    assert (round(capture_minus_sensor, 2), round(sensor_minus_gnss, 3), round(capture_minus_gnss, 3)) == (0.92, 0.848, 1.767)

    recording, events = read(HDL32E)
    clocks = recording.facts["clocks"]
    assert clocks["timeline"].startswith("GNSS time") and clocks["pps"] == "absent" and clocks["gnss_offsets_from"] == "1 GPRMC arrivals"
    assert clocks["sensor_minus_gnss_s"] == pytest.approx(sensor_minus_gnss, abs=1e-9)
    assert clocks["capture_minus_gnss_s"] == pytest.approx(capture_minus_gnss, abs=1e-9)
    assert clocks["capture_minus_sensor_s"] == pytest.approx(capture_minus_sensor, abs=1e-4)  # a median over every 16th packet
    fixes = [e for e in events if isinstance(e, RecordedFix)]
    assert recording.facts["fixes_in_file"] == len(fixes) == 2  # 22:06:32 (in the first packet, 1.2 s old) and 22:06:33
    assert [f.stamp for f in fixes] == [0.0, 1.0] and recording.geo.zero_ns == epoch - 10**9  # time zero: the first fix's epoch
    assert [f.fix.quality for f in fixes] == [2, 2] and recording.geo.origin_source == "first fix"  # RMC mode D: differential
    # scans on GNSS time: the sensor's clock less its offset; the recording spans the data packets, after the first fix
    first_us = data[0][1]
    assert recording.t_start == pytest.approx((sensor_ns(first_us) - epoch) / 1e9 - sensor_minus_gnss + 1.0, abs=1e-9)
    assert 0.35 < recording.t_start < recording.t_end < 1.1
    stamps = [e.stamp for e in events]
    assert stamps == sorted(stamps) and min(stamps) == 0.0  # in time order, nothing before time zero


def test_the_vlp16_capture_whose_factory_bytes_say_hdl32e_is_decoded_as_the_vlp16_its_packets_are():
    with pytest.raises(RuntimeError, match=r"Expected model ID <34> in packet, got <33>"):  # velodyne_decoder: bytes say HDL-32E
        next(vd.read_pcap(str(VLP16), vd.Config(model=vd.Model.VLP16)))
    recording, events = read(VLP16)
    facts = recording.facts
    assert facts["sensor"] == "VLP-16" and "VLP-16" in recording.lidar_source
    note = facts["sensor_note"]
    assert note.startswith("factory bytes say HDL-32E (0x21), but the packets are a VLP-16's: 1327 us per packet (HDL-32E: 553, VLP-16: 1327)")
    assert re.search(r"\(4[78]\.\d Hz as HDL-32E, (19\.9|20\.0) Hz as VLP-16; they spin 5-20 Hz\), 16 lasers fired twice per block", note)
    assert note.endswith("decoded as VLP-16; Puck Hi-Res sends the same packets but reports 0x24")
    model = BY_NAME["VLP-16"]
    decoded = scans(events)
    assert len(decoded) == facts["revolutions"] == 10 and facts["partial_revolutions_dropped"] == 2
    for scan in decoded:
        assert set(np.unique(scan.points["ring"])) == set(range(16))
        # each point on its laser's VLP-16 beam (+-15 deg in 2 deg steps), none on an HDL-32E one
        assert np.abs(elevations(scan.points) - model.elevation_deg[scan.points["ring"]]).max() < 0.01
        assert scan.points["time"].max() == pytest.approx(1 / facts["rotation_hz"], rel=0.05)
    assert facts["rotation_hz"] == pytest.approx(19.98, abs=0.02)
    clocks = facts["clocks"]  # no NMEA: the capture clock, 1430.6 s ahead of the free-running sensor clock
    assert clocks["timeline"].startswith("capture clock") and clocks["capture_minus_sensor_s"] == pytest.approx(1430.58, abs=0.01)
    assert facts["fixes_in_file"] == 0 and not [e for e in events if isinstance(e, RecordedFix)]


@pytest.mark.parametrize(("name", "resolution"), [("VLP-32C", 0.004), ("VLS-128", 0.004), ("HDL-32E", 0.002), ("VLP-16", 0.002)])
def test_every_model_decodes_with_its_own_geometry_and_timing(tmp_path, name, resolution):
    model = BY_NAME[name]
    stream(model, tmp_path / "s.pcap", packets=int(0.35 / model.packet_s[0]), resolution_m=resolution)
    recording, events = read(tmp_path / "s.pcap")
    assert (recording.facts["sensor"], recording.facts["sensor_note"]) == (name, "")
    assert recording.facts["rotation_hz"] == pytest.approx(10.0, rel=1e-3)
    decoded = scans(events)
    assert len(decoded) == recording.facts["revolutions"] >= 2
    for scan in decoded:
        points = scan.points
        assert set(np.unique(points["ring"])) == set(range(model.lasers))
        assert np.abs(elevations(points) - model.elevation_deg[points["ring"]]).max() < 0.01
        rng = np.sqrt(points["x"].astype(float) ** 2 + points["y"].astype(float) ** 2 + points["z"].astype(float) ** 2)
        assert np.abs(rng - ranges(model)[points["ring"]]).max() < resolution
        assert points["time"].max() == pytest.approx(0.1, abs=2 * model.packet_s[0])  # one revolution at 10 Hz


def test_streams_that_are_no_supported_sensor_are_named_in_one_line(tmp_path):
    vlp32c = BY_NAME["VLP-32C"]
    stream(vlp32c, tmp_path / "claims.pcap", packets=300, product_id=0x22)  # claims VLP-16, is a VLP-32C: decoded as one
    assert read(tmp_path / "claims.pcap")[0].facts["sensor"] == "VLP-32C"
    stream(vlp32c, tmp_path / "odd.pcap", packets=300, packet_s=900e-6)  # 900 us per packet: no model's timing
    cases = {
        "odd.pcap": r"factory bytes say VLP-32C \(0x28\) but the packets fit no supported model: 900 us per packet \(VLP-32C: 664\)",
        "ab.pcap": r"a VLP-32A or VLP-32B \(product id 0x23: velodyne_decoder cannot tell which\): not supported",
        "velarray.pcap": r"a Velarray \(product id 0x31\): not supported",
    }
    stream(vlp32c, tmp_path / "ab.pcap", packets=300, product_id=0x23)
    stream(vlp32c, tmp_path / "velarray.pcap", packets=300, product_id=0x31)
    for name, message in cases.items():
        with pytest.raises(ValueError, match=message) as error:
            pcap.read(tmp_path / name, PLACE)
        assert "\n" not in str(error.value)
    seen = Evidence(300, 0x00, 0x37, 553e-6, 0.1953, False, lower_bank=True)
    with pytest.raises(ValueError, match=r"HDL-64E data .*0xDDFF.*: not supported"):
        identify(seen, "x.pcap")
    unlabelled = Evidence(300, 0x00, 0x37, 553e-6, 0.1953, False, lower_bank=False)  # HDL-32E firmware before 2016 sets no bytes
    assert identify(unlabelled, "x.pcap").model.name == "HDL-32E"
    # riverbench's own 60 s export of dam_lock's chamber (0x21, 553 us, 10 Hz): its ranges made channels j and j + 16 alike,
    # and the layout test refused the capture; the timing and rotation the bytes claim decide, and the note says so
    walls = Evidence(300, 0x21, 0x37, 553e-6, 0.166, True, lower_bank=False)
    found = identify(walls, "x.pcap")
    assert found.model.name == "HDL-32E" and "looked like 16 lasers fired twice" in found.note
    assert all(m.laser_of_ring.dtype == np.uint16 and sorted(m.laser_of_ring) == list(range(m.lasers)) for m in MODELS)


def test_a_real_capture_replays_with_the_default_stack_and_says_what_it_found(tmp_path):
    result = replay(HDL32E, scenarios.load("quickstart"), tmp_path / "run", workers=1, report=True)
    run = result.metrics["run"]
    assert run["scans"] == 7 and run["fixes"] == 2 and run["failures"] == [] and run["warnings"] == []
    gicp = result.metrics["matchers"]["gicp"]
    assert gicp["success"] == 1.0 and gicp["gated"] == 0.0  # no partial revolution left to gate the whole ones
    assert run["recording"]["time_zero_utc"] == "2012-12-11T22:06:32+00:00" and 0.35 < run["t_start"] < run["t_end"] < 1.1
    assert run["realtime_factor"] == pytest.approx(run["duration_s"] / run["wall_s"], abs=0.05) and run["duration_s"] == pytest.approx(0.66, abs=0.01)
    assert run["anchor"] == {"estimator": "gps_only", "t": pytest.approx(run["t_start"], abs=0.1), "heading": "none"}  # parked
    report = (result.out_dir / "report.md").read_text()
    assert "clocks: capture − sensor +0.919 s, sensor − GNSS +0.848 s, capture − GNSS +1.767 s (GNSS offsets from 1 GPRMC arrivals)" in report
    assert "7 whole revolutions replayed, 2 partial ones dropped · 2 of the 2 GPRMC fixes in the file read" in report
    # a gate that refuses most scans is named, with the key that changes it
    strict = replay(HDL32E, scenarios.load("quickstart", set=["matchers.gicp.params.gate_min_points=60000"]), tmp_path / "strict", report=False)
    (warning,) = strict.metrics["run"]["warnings"]
    assert warning.startswith("gicp: gate_min_points refused 7 of 7 scans (e.g. 'too few points:")
    assert warning.endswith("change it with --set matchers.gicp.params.gate_min_points=VALUE")


def test_a_truncated_capture_is_one_line_and_exit_2_and_writes_nothing(tmp_path):
    data = HDL32E.read_bytes()
    (tmp_path / "cut.pcap").write_bytes(data[: len(data) - 100])  # the last record loses 100 of its 1248 bytes
    with pytest.raises(ValueError, match=r"cut.pcap: truncated: record 1325 at byte \d+ holds 1148 of its 1248 bytes$"):
        pcap.read(tmp_path / "cut.pcap", PLACE)
    (tmp_path / "header.pcap").write_bytes(data[:24] + data[24:30])  # a record cut inside its header
    with pytest.raises(ValueError, match=r"truncated: record 0 at byte 24 is cut inside its header"):
        pcap.read(tmp_path / "header.pcap", PLACE)
    (tmp_path / "ng.pcapng").write_bytes(b"\x0a\x0d\x0d\x0a" + bytes(40))
    with pytest.raises(ValueError, match=r"a pcapng capture; convert it to pcap first \(editcap -F pcap ng.pcapng out.pcap\)"):
        pcap.read(tmp_path / "ng.pcapng", PLACE)
    before = sorted(p.name for p in tmp_path.iterdir())
    cli = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "replay", "cut.pcap", "--scenario", "quickstart", "--out", "out", "--quiet"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert cli.returncode == 2 and len(cli.stderr.strip().splitlines()) == 1 and "truncated" in cli.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_the_sensor_clock_counts_on_across_the_top_of_the_hour(tmp_path):
    """A stream whose sensor clock passes 14:00:00 (its microseconds past the hour wrap to 0) stays in one piece."""
    model = BY_NAME["HDL-32E"]
    data = stream(model, tmp_path / "s.pcap", packets=700)
    raw = bytearray((tmp_path / "s.pcap").read_bytes())
    offset, shift = 24, 3_600_000_000 - 200_000  # the stream now starts 0.2 s before the hour
    for k in range(len(data)):
        at = offset + 16 + 42 + 1200
        struct.pack_into("<I", raw, at, (int(data["stamp"][k]) + shift) % 3_600_000_000)
        offset += 16 + 42 + 1206
    (tmp_path / "wrap.pcap").write_bytes(bytes(raw))
    recording, events = read(tmp_path / "wrap.pcap")
    stamps = [s.stamp for s in scans(events)]
    assert len(stamps) >= 3 and np.allclose(np.diff(stamps), 0.1, atol=1e-3)
    assert math.isclose(recording.t_end - recording.t_start, 699 * model.packet_s[0], abs_tol=2e-6)
