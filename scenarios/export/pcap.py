"""Velodyne HDL-32E packets in a libpcap capture, as the sensor streams them over Ethernet.

Data packets, UDP port 2368 (HDL-32E user's manual, appendix B, and Velodyne's HDL-32E packet
structure application note): a 1206-byte payload of 12 blocks, one block per firing sequence
(46.08 us), each 0xEEFF, the azimuth (uint16, 0.01 deg) at that firing and 32 x (distance uint16 in
2 mm, reflectivity uint8) in laser-id (firing) order, distance 0 for a laser without a return; then
the time of the packet's first firing (uint32 little endian, microseconds past the UTC hour) and
the factory bytes 0x37 (strongest return) and 0x21 (HDL-32E).

- Azimuth: the manual's, clockwise from the sensor's forward axis (the lidar frame's x here, which
  decoders report as x forward, y left), i.e. minus the simulator's counter-clockwise angle from x.
  The rotation phase is read back from the points' own directions and times, so a scenario's
  `start_azimuth_deg` needs no configuration (an empty scan keeps the previous phase).
- Reflectivity: the sensor's calibrated reflectivity byte, 0-100 for diffuse targets as the
  simulated intensity is, rounded (values above 100 are retro-reflectors, up to 255).
- Packets: each revolution is its own ceil(firings / 12) packets (10 Hz: 2170 firings, 181
  packets); the last packet's spare blocks continue the rotation with no returns.
- Position packets, UDP port 8308, one after every 14th data packet: the manuals of Velodyne's later
  sensors (VLP-16, VLP-32C, VLS-128) give "the ratio of data packets to position packets is about
  14 to 1"; the HDL-32E manual states no rate. 512-byte payload with the HDL-32E layout: gyro,
  temperature and accelerometer fields (left zero), the timestamp at byte 198, the PPS status at
  202 (2 = locked), and at 206 the $GPRMC sentence (GP talker whatever systems the receiver tracks: a
  multi-GNSS receiver feeding the sensor is set to it, e.g. u-blox CFG-NMEA main talker ID) with CR/LF, null-padded (a sentence with
  5-decimal minutes is longer than the manual's 72-byte field; the bytes after it are unused). The
  sentence is the receiver's RMC of its latest fix before the packet; before the first fix the
  NMEA and PPS fields are zero, as the manuals describe a sensor without GPS. A fix after the last
  of them (an epoch at the stretch's very end) gets one more position packet, at its own time (or
  the last data packet's, when that is later).
- Frames: Ethernet broadcast from 192.168.1.201 (the factory address) to 255.255.255.255, IPv4,
  UDP without checksum; record times are the packets' first-firing UTC times (microseconds).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from riverbench.angles import wrap_deg
from riverbench.unixtime import unix_ns
from scenarios.export.frames import Frame, StreamInfo
from sim.gnss_fix import GnssFix
from sim.lidar import FIRING_CYCLE_S, LASER_INTERVAL_S, HDL32EConfig
from sim.nmea import rmc

DATA_PORT = 2368
POSITION_PORT = 8308
SENSOR_IP = bytes([192, 168, 1, 201])
BROADCAST_IP = bytes([255, 255, 255, 255])
SENSOR_MAC = bytes.fromhex("607688000001")  # Velodyne's MAC prefix 60:76:88
BLOCKS = 12
LASERS = 32
DISTANCE_UNIT_M = 0.002
DATA_PER_POSITION = 14
RATE_RANGE_HZ = (5.0, 20.0)  # 300-1200 RPM
RETURN_STRONGEST = 0x37
PRODUCT_HDL32E = 0x21
PPS_LOCKED = 2
US_PER_HOUR = 3_600_000_000
PHASE_TOLERANCE_DEG = 0.005  # half the packet's azimuth resolution
TIME_TOLERANCE_S = 1e-7

BLOCK = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("laser", [("distance", "<u2"), ("reflectivity", "u1")], (LASERS,))])
DATA = np.dtype([("block", BLOCK, (BLOCKS,)), ("stamp", "<u4"), ("return_mode", "u1"), ("product", "u1")])
POSITION = np.dtype([("imu", "V198"), ("stamp", "<u4"), ("pps", "u1"), ("reserved", "V3"), ("nmea", "S306")])
HEADERS = 14 + 20 + 8  # Ethernet, IPv4, UDP
PCAP_HEADER = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)  # microsecond times, Ethernet


def write(info: StreamInfo, frames: Iterable[Frame], path: Path) -> dict[str, int]:
    """Stream the frames' data and position packets into the pcap file `path`; returns the counts written."""
    rate = info.lidar_rate_hz
    if not RATE_RANGE_HZ[0] <= rate <= RATE_RANGE_HZ[1]:
        raise ValueError(f"pcap: the HDL-32E spins at {RATE_RANGE_HZ[0]:g}-{RATE_RANGE_HZ[1]:g} Hz, the lidar rate is {rate:g} Hz")
    epoch_us = unix_ns(info.epoch_utc) // 1000
    n_firings = int((1.0 / rate) / FIRING_CYCLE_S)  # as sim.HDL32E counts a revolution's firings
    packet_offset = np.arange(-(-n_firings // BLOCKS)) * BLOCKS * FIRING_CYCLE_S
    phase = -HDL32EConfig.model_fields["start_azimuth_deg"].default % 360.0
    latest: list[GnssFix] = []  # the last fix of the frames written so far
    relayed = -math.inf  # the stamp of the newest fix a position packet carried
    counts = {"packets": 0, "points": 0, "position_packets": 0}
    path = Path(path)
    try:
        with path.open("wb") as out:
            out.write(PCAP_HEADER)
            for frame in frames:
                points = frame.scan.points
                phase = rotation_phase(points, rate, phase)
                packet_us = epoch_us + np.rint((frame.stamp + packet_offset) * 1e6).astype(np.int64)
                data = data_packets(points, n_firings, rate, phase, packet_us % US_PER_HOUR)
                after = np.arange((DATA_PER_POSITION - 1 - counts["packets"]) % DATA_PER_POSITION, len(data), DATA_PER_POSITION)
                fixes = latest + frame.fixes
                position = position_packets(fixes, frame.stamp + packet_offset[after], data["stamp"][after])
                out.write(interleaved(records(data, packet_us, DATA_PORT), records(position, packet_us[after], POSITION_PORT), after))
                latest = fixes[-1:]
                if len(after) and fixes:
                    relayed = max(relayed, max((f.stamp for f in fixes if f.stamp <= frame.stamp + packet_offset[after[-1]]), default=relayed))
                counts["packets"] += len(data)
                counts["points"] += len(points)
                counts["position_packets"] += len(position)
            if latest and latest[0].stamp > relayed:  # the stream's last fix came after its last position packet
                at = np.array([max(epoch_us + round(latest[0].stamp * 1e6), int(packet_us[-1]))])
                out.write(records(position_packets(latest, np.array([latest[0].stamp]), at % US_PER_HOUR), at, POSITION_PORT).tobytes())
                counts["position_packets"] += 1
    except BaseException:
        path.unlink(missing_ok=True)
        raise
    return counts


def rotation_phase(points: np.ndarray, rate_hz: float, previous: float) -> float:
    """Sensor azimuth (deg, the manual's convention) at the scan's stamp, from its points; `previous` if it has none."""
    if len(points) == 0:
        return previous
    azimuth = np.degrees(np.arctan2(-points["y"].astype(np.float64), points["x"]))
    start = azimuth - 360.0 * rate_hz * points["time"]
    offset = wrap_deg(start - start[0])
    if np.ptp(offset) > PHASE_TOLERANCE_DEG:
        raise ValueError(f"pcap: the points do not lie on one rotation at {rate_hz:g} Hz (azimuth spread {np.ptp(offset):.3f} deg)")
    return float((start[0] + np.median(offset)) % 360.0)


def data_packets(points: np.ndarray, n_firings: int, rate_hz: float, phase_deg: float, stamps: np.ndarray) -> np.ndarray:
    """The revolution's data payloads (in-packet `stamps`): block k is firing sequence k, each point at its firing and laser."""
    laser = points["ring"].astype(np.int64)
    since_firing = points["time"].astype(np.float64) - laser * LASER_INTERVAL_S
    firing = np.rint(since_firing / FIRING_CYCLE_S).astype(np.int64)
    off_grid = (laser >= LASERS) | (firing < 0) | (firing >= n_firings)
    off_grid |= np.abs(since_firing - firing * FIRING_CYCLE_S) > TIME_TOLERANCE_S
    if off_grid.any():
        i = int(np.argmax(off_grid))
        raise ValueError(f"pcap: point {i} (ring {laser[i]}, time {points['time'][i]:.9f} s) is no HDL-32E firing at {rate_hz:g} Hz")
    distance = np.rint(np.sqrt(sum(points[axis].astype(np.float64) ** 2 for axis in "xyz")) / DISTANCE_UNIT_M)
    unfit = (distance < 1) | (distance > np.iinfo(np.uint16).max)
    if unfit.any():
        raise ValueError(f"pcap: a range of {distance[unfit][0] * DISTANCE_UNIT_M:.3f} m does not fit the packet's uint16 x 2 mm distance")
    n_packets = len(stamps)
    data = np.zeros(n_packets, DATA)
    block = data["block"]
    block["flag"] = 0xEEFF
    rotation = phase_deg + 360.0 * rate_hz * FIRING_CYCLE_S * np.arange(n_packets * BLOCKS)
    block["azimuth"] = (np.rint(rotation * 100.0).astype(np.int64) % 36000).reshape(n_packets, BLOCKS)
    where = (firing // BLOCKS, firing % BLOCKS, laser)
    block["laser"]["distance"][where] = distance.astype(np.uint16)
    block["laser"]["reflectivity"][where] = np.clip(np.rint(points["intensity"]), 0, 255).astype(np.uint8)
    if np.count_nonzero(block["laser"]["distance"]) != len(points):
        raise ValueError("pcap: two returns of one laser firing (the strongest-return mode carries one)")
    data["stamp"] = stamps
    data["return_mode"] = RETURN_STRONGEST
    data["product"] = PRODUCT_HDL32E
    return data


def position_packets(fixes: list[GnssFix], times: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """Position payloads at scenario `times` (in-packet `stamps`), each with the RMC of the latest fix by then."""
    packets = np.zeros(len(times), POSITION)
    packets["stamp"] = stamps
    latest = np.searchsorted([fix.stamp for fix in fixes], times, side="right") - 1
    sentences = [(rmc(fix, gps_talker=True) + "\r\n").encode("ascii") for fix in fixes]  # the $GPRMC the manuals name
    has_fix = latest >= 0
    packets["nmea"][has_fix] = [sentences[i] for i in latest[has_fix]]
    packets["pps"][has_fix] = PPS_LOCKED
    return packets


def records(payloads: np.ndarray, unix_us: np.ndarray, port: int) -> np.ndarray:
    """pcap records of the payloads: record header, then Ethernet, IPv4 and UDP from the sensor to broadcast."""
    size = payloads.dtype.itemsize
    out = np.zeros(
        len(payloads),
        [("ts_sec", "<u4"), ("ts_usec", "<u4"), ("incl_len", "<u4"), ("orig_len", "<u4"), ("headers", "u1", (HEADERS,)), ("payload", payloads.dtype)],
    )
    out["ts_sec"], out["ts_usec"] = np.divmod(unix_us, 1_000_000)
    out["incl_len"] = out["orig_len"] = HEADERS + size
    out["headers"] = np.frombuffer(headers(port, size), np.uint8)
    out["payload"] = payloads
    return out


def interleaved(data: np.ndarray, position: np.ndarray, after: np.ndarray) -> bytes:
    """The records in stream order: position record i right after data record after[i]."""
    chunks = np.split(data, after + 1)
    return b"".join(chunk.tobytes() + (position[i].tobytes() if i < len(position) else b"") for i, chunk in enumerate(chunks))


def headers(port: int, size: int) -> bytes:
    """Ethernet (broadcast), IPv4 (don't fragment, with checksum) and UDP (no checksum) headers of a `size`-byte payload."""
    ethernet = b"\xff" * 6 + SENSOR_MAC + b"\x08\x00"
    ip = bytearray(struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + 8 + size, 0, 0x4000, 64, 17, 0, SENSOR_IP, BROADCAST_IP))
    total = sum(struct.unpack("!10H", ip))
    total = (total & 0xFFFF) + (total >> 16)
    ip[10:12] = struct.pack("!H", ~((total & 0xFFFF) + (total >> 16)) & 0xFFFF)
    return ethernet + bytes(ip) + struct.pack("!HHHH", port, port, 8 + size, 0)
