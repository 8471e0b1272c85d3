"""The pcap export read back by independent consumers: velodyne_decoder (points, rings, times and
the position packets' GPRMC) and dpkt plus byte-level checks (libpcap, Ethernet, IPv4, UDP)."""

import dataclasses
import math
import struct
from datetime import UTC, datetime, timedelta

import dpkt
import numpy as np
import pytest
import velodyne_decoder as vd

import scenarios
from scenarios.export import pcap
from scenarios.export.frames import Frame, open_stream
from sim.lidar import FIRING_CYCLE_S, HDL32E_ELEVATION_DEG
from sim.scan import POINT_DTYPE, Scan

FIRINGS = int(0.1 / FIRING_CYCLE_S)  # one 10 Hz revolution
PACKETS_PER_SCAN = math.ceil(FIRINGS / 12)


@pytest.fixture(scope="module")
def stream(tmp_path_factory):
    """1.5 s beside the canal walls (about 13,000 points a scan), written as one capture."""
    info, frames = open_stream(scenarios.load("canal_multipath", set=["stretch={start_s = 60.0, end_s = 61.5}"]))
    frames = list(frames)
    path = tmp_path_factory.mktemp("pcap") / "canal.pcap"
    counts = pcap.write(info, frames, path)
    return info, frames, path, counts


def udp_payloads(path, port):
    """(record time, payload) of every UDP datagram to `port`, as dpkt parses the capture."""
    with open(path, "rb") as f:
        packets = [(ts, dpkt.ethernet.Ethernet(buf)) for ts, buf in dpkt.pcap.Reader(f)]
    return [(ts, bytes(eth.data.data.data)) for ts, eth in packets if eth.data.data.dport == port]


def test_decoder_gives_back_every_point(stream):
    info, frames, path, counts = stream
    # VeloView's HDL-32E calibration (bundled with the decoder): every beam from the sensor's centre,
    # as the simulator casts them; the decoder's built-in default adds the real unit's per-laser
    # vertical offsets (a 28.83 mm focal distance), which the simulator does not model.
    config = vd.Config(model=vd.Model.HDL32E, calibration=vd.get_bundled_calibration("HDL-32E.yml"), timestamp_first_packet=True)
    scans = list(vd.read_pcap(str(path), config, as_pcl_structs=True))
    assert [len(s.points) for s in scans] == [len(f.scan.points) for f in frames]  # one decoded scan per revolution
    got = np.concatenate([s.points for s in scans])
    want = np.concatenate([f.scan.points for f in frames])
    assert counts["points"] == len(want) > 150_000

    epoch = info.epoch_utc.timestamp()
    got_t = np.concatenate([s.stamp.device + s.points["time"].astype(np.float64) for s in scans])
    want_t = np.concatenate([epoch + f.stamp + f.scan.points["time"].astype(np.float64) for f in frames])
    assert np.abs(got_t - want_t).max() < 1e-6  # the packet's microsecond stamp; same point order

    laser_of_ring = np.argsort(HDL32E_ELEVATION_DEG)  # decoders number rings bottom-up
    np.testing.assert_array_equal(laser_of_ring[got["ring"]], want["ring"])
    np.testing.assert_array_equal(got["intensity"], np.clip(np.rint(want["intensity"]), 0, 255))

    g = np.stack([got[a] for a in "xyz"], axis=1).astype(np.float64)
    w = np.stack([want[a] for a in "xyz"], axis=1).astype(np.float64)
    # the simulated ranges are already on the 2 mm grid: the packet carries them exactly
    assert np.abs(np.linalg.norm(g, axis=1) - np.linalg.norm(w, axis=1)).max() < 1e-4
    elevation = np.degrees(np.arcsin(g[:, 2] / np.linalg.norm(g, axis=1)) - np.arcsin(w[:, 2] / np.linalg.norm(w, axis=1)))
    assert np.abs(elevation).max() < 1e-4
    # azimuth: the block's 0.01 deg, the decoder's per-laser interpolation rounded to 0.01 deg again
    azimuth = np.degrees(np.arctan2(g[:, 1], g[:, 0]) - np.arctan2(w[:, 1], w[:, 0]))
    assert np.abs((azimuth + 180.0) % 360.0 - 180.0).max() < 0.011
    horizontal = np.hypot(*(g - w)[:, :2].T)
    assert (horizontal <= np.hypot(*w[:, :2].T) * np.radians(0.011) + 1e-4).all()


def test_data_packets_as_the_manual_lays_them_out(stream):
    info, frames, path, counts = stream
    packets = udp_payloads(path, pcap.DATA_PORT)
    assert len(packets) == counts["packets"] == PACKETS_PER_SCAN * len(frames)
    payload = np.frombuffer(b"".join(p for _, p in packets), np.uint8).reshape(len(packets), 1206)
    blocks = payload[:, :1200].reshape(len(packets), 12, 100)
    assert (blocks[:, :, 0] == 0xFF).all() and (blocks[:, :, 1] == 0xEE).all()
    assert (payload[:, 1204] == 0x37).all() and (payload[:, 1205] == 0x21).all()
    azimuth = (blocks[:, :, 2].astype(np.int64) | blocks[:, :, 3].astype(np.int64) << 8).reshape(len(frames), -1)
    # clockwise from forward; the simulator's revolutions start behind the sensor
    np.testing.assert_array_equal(azimuth[:, 0], 18000)
    step = np.diff(azimuth, axis=1) % 36000
    assert set(np.unique(step)) == {16, 17}  # 0.166 deg per 46.08 us firing at 10 Hz
    usec = payload[:, 1200:1204].copy().view("<u4").ravel()
    record_us = np.array([round(ts * 1e6) for ts, _ in packets])
    np.testing.assert_array_equal(usec, record_us % 3_600_000_000)
    first = datetime.fromtimestamp(packets[0][0], UTC)
    assert abs(first - (info.epoch_utc + timedelta(seconds=frames[0].stamp))) < timedelta(microseconds=1)


def nmea_fields(sentence):
    """Check the NMEA checksum by hand and split the fields."""
    assert sentence.startswith("$") and sentence.endswith("\r\n")
    body, given = sentence[1:-2].split("*")
    check = 0
    for ch in body:
        check ^= ord(ch)
    assert given == f"{check:02X}"
    return body.split(",")


def test_position_packets_carry_the_receivers_gprmc(stream):
    info, frames, path, counts = stream
    packets = udp_payloads(path, pcap.POSITION_PORT)
    assert len(packets) == counts["position_packets"] == counts["packets"] // 14
    fixes = [fix for frame in frames for fix in frame.fixes]
    fix_utc = np.array([(info.epoch_utc + timedelta(seconds=fix.stamp)).timestamp() for fix in fixes])
    for ts, payload in packets:
        assert len(payload) == 512
        telemetry = vd.TelemetryPacket(np.frombuffer(payload, np.uint8))
        assert telemetry.usec_since_toh == round(ts * 1e6) % 3_600_000_000
        assert telemetry.pps_status == vd.TelemetryPacket.PpsStatus.LOCKED
        f = nmea_fields(telemetry.nmea_sentence)
        fix = fixes[np.searchsorted(fix_utc, ts + 1e-9, side="right") - 1]  # the latest fix by then
        assert f[0] == "GPRMC" and f[2] == "A" and f[9] == f"{info.epoch_utc:%d%m%y}"
        when = datetime.fromisoformat(fix.utc)
        assert (
            abs(
                int(f[1][:2]) * 3600
                + int(f[1][2:4]) * 60
                + float(f[1][4:])
                - (when.hour * 3600 + when.minute * 60 + when.second + when.microsecond / 1e6)
            )
            <= 0.005
        )
        lat = (int(f[3][:2]) + float(f[3][2:]) / 60.0) * (1 if f[4] == "N" else -1)
        lon = (int(f[5][:3]) + float(f[5][3:]) / 60.0) * (1 if f[6] == "E" else -1)
        assert abs(lat - fix.lat) < 1e-7 and abs(lon - fix.lon) < 1e-7  # 5 decimals of minutes
        lon_d, lat_d, _ = telemetry.gps_position
        assert abs(lat_d - fix.lat) < 1e-7 and abs(lon_d - fix.lon) < 1e-7


def test_capture_is_valid_libpcap(stream):
    info, frames, path, counts = stream
    raw = path.read_bytes()
    magic, major, minor, zone, sigfigs, snaplen, linktype = struct.unpack_from("<IHHiIII", raw)
    assert (magic, major, minor, zone, sigfigs, snaplen, linktype) == (0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)
    offset, last, n = 24, 0.0, 0
    while offset < len(raw):
        sec, usec, incl, orig = struct.unpack_from("<IIII", raw, offset)
        frame = raw[offset + 16 : offset + 16 + incl]
        assert incl == orig == len(frame) in (42 + 1206, 42 + 512) and usec < 1_000_000 and sec + usec * 1e-6 >= last
        assert frame[:6] == b"\xff" * 6 and frame[12:14] == b"\x08\x00"
        ip = frame[14:34]
        total = sum(struct.unpack("!10H", ip))
        assert (total & 0xFFFF) + (total >> 16) == 0xFFFF  # header checksum
        assert ip[9] == 17 and ip[12:16] == bytes([192, 168, 1, 201]) and ip[16:20] == b"\xff" * 4
        assert struct.unpack("!H", ip[2:4])[0] == incl - 14 and struct.unpack("!H", frame[38:40])[0] == incl - 34
        offset, last, n = offset + 16 + incl, sec + usec * 1e-6, n + 1
    assert offset == len(raw) and n == counts["packets"] + counts["position_packets"]
    with open(path, "rb") as f:
        assert sum(1 for _ in dpkt.pcap.Reader(f)) == n


def test_bad_input_is_one_error_and_no_file(stream, tmp_path):
    info, frames, _, _ = stream
    with pytest.raises(ValueError, match="5-20 Hz"):
        pcap.write(dataclasses.replace(info, lidar_rate_hz=25.0), frames[:1], tmp_path / "fast.pcap")
    off_grid = np.zeros(1, POINT_DTYPE)
    off_grid[["x", "time"]] = (5.0, 0.5e-6)
    bad = Frame(1, Scan(frames[0].stamp + 0.1, off_grid), frames[0].base_pose, frames[0].lidar_pose)
    with pytest.raises(ValueError, match="no HDL-32E firing"):
        pcap.write(info, [frames[0], bad], tmp_path / "bad.pcap")
    assert not list(tmp_path.iterdir())
