"""A Velodyne capture (libpcap) read into time-ordered scans and fixes.

A first pass reads the whole capture (a truncated one fails here, before anything is written): which sensor it
is (scenarios.replay.velodyne: the factory bytes checked against the data), its clocks and the one timeline they
give (scenarios.replay.clocks) and its GPRMC sentences. The second pass, lazily:
- data packets (1206-byte payloads) are cut into revolutions where the scenario's lidar starts one ([lidar]
  start_azimuth_deg, by default behind the sensor; scenarios.replay.revolutions) and each whole revolution is
  decoded by velodyne_decoder with the model's VeloView calibration (every beam from the sensor's centre, as the
  simulator casts them; velodyne_decoder's built-in one adds each emitter's vertical offset, up to 1.7 cm on an
  HDL-32E). A scan is stamped with its first packet's time
  on the timeline, each point with its firing time since (the sensor's own clock); rings come back as laser ids
  (firing order), as the simulator numbers them. Partial revolutions are dropped and counted. Dual-return data
  keeps each firing's strongest return (the bench's sensor model, and its export, are single-return).
- position packets (512 bytes) relay the receiver's latest GPRMC: each new sentence is a fix stamped with its own
  epoch (UTC, 0.01 s) on the timeline, with position, quality and course but no altitude, HDOP or satellites
  (see scenarios.replay.fixes: the estimators take it as an open-sky fix of HDOP 1). None is dropped: events are
  held for the longest time the capture's sentences took to arrive, plus two revolutions.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import velodyne_decoder as vd
from velodyne_decoder.velodyne_decoder_pylib import TimePair

from riverbench.unixtime import unix_ns
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import capture, fixes
from scenarios.replay.clocks import Arrival, Clocks, ClockSurvey, SensorClock
from scenarios.replay.recording import Event, Geo, Place, RecordedFix, Recording, TimeOrder
from scenarios.replay.revolutions import Cutter, Packet, Revolution
from scenarios.replay.velodyne import DATA_BYTES, DUAL, POSITION_BYTES, Evidence, Identified, evidence, identify
from sim import nmea
from sim.scan import POINT_DTYPE, Scan

SAMPLE_PACKETS = 2000
"""Data packets the sensor model is identified from (the first ones: 1.1 s of an HDL-32E)."""
STAMP_AT = DATA_BYTES - 6
STRONGEST_RETURN = 1
"""velodyne_decoder's return_type bit of a strongest return (1 strongest, 2 last, 3 both)."""


def read(path: str | Path, place: Place) -> Recording:
    """Read the whole capture once: its sensor, clocks, revolutions and fixes; ValueError (one line) when it cannot be replayed."""
    path = Path(path)
    survey, clock, sample, stamps = ClockSurvey(), SensorClock(), [], []
    latest, first_position, sentences = "", None, 0
    for datagram in capture.datagrams(path):
        if len(datagram.payload) == DATA_BYTES:
            sensor = clock.ns(int.from_bytes(datagram.payload[STAMP_AT : STAMP_AT + 4], "little"), datagram.ns)
            survey.data(datagram.ns, sensor)
            if len(sample) < SAMPLE_PACKETS:
                sample.append(datagram.payload)
                stamps.append(sensor // 1000)
        elif len(datagram.payload) == POSITION_BYTES:
            telemetry = vd.TelemetryPacket(np.frombuffer(datagram.payload, np.uint8))
            survey.position(int(telemetry.pps_status.value))
            line = telemetry.nmea_sentence.strip()
            if line and line != latest:
                sentences += 1
                fields = rmc(line)
                if fields is not None:
                    survey.sentence(Arrival(clock.ns(telemetry.usec_since_toh, datagram.ns), datagram.ns, epoch_ns(fields)))
                    if first_position is None and fields["valid"] and math.isfinite(fields["lat"]):
                        first_position = (fields["lat"], fields["lon"], place.origin[2])
            latest = line or latest
    if not survey.data_packets:
        raise ValueError(f"{path}: no Velodyne data packets (UDP payloads of {DATA_BYTES} bytes)")
    seen = evidence(sample, np.asarray(stamps))
    sensor = identify(seen, str(path))
    revolution_s = revolution_seconds(seen, sensor)
    clocks = survey.clocks(revolution_s)
    first, last = clocks.utc_ns(survey.first_sensor_ns), clocks.utc_ns(survey.last_sensor_ns)
    geo = Geo.choose(place, min([first, *(a.epoch_ns for a in survey.arrivals)]), first_position)  # no event before time zero
    mode = {0x37: "strongest return", 0x38: "last return", DUAL: "dual return: strongest kept"}.get(seen.return_mode, "unknown return mode")
    facts = {
        "sensor": sensor.model.name,
        "sensor_note": sensor.note,
        "return_mode": mode,
        "rotation_hz": 1.0 / revolution_s,
        "data_packets": survey.data_packets,
        "revolutions": 0,  # counted as the events are read
        "partial_revolutions_dropped": 0,
        "fixes_in_file": sentences,
        "clocks": clocks.describe(),
    }
    return Recording(
        path,
        "pcap",
        f"{sensor.model.name} data packets ({survey.data_packets}; {1.0 / revolution_s:.2f} Hz, {mode})",
        "GPRMC of the position packets" if sentences else "none (the position packets relay no NMEA)",
        geo,
        geo.seconds(first),
        geo.seconds(last),
        events=lambda: events(path, geo, place.start_azimuth_deg, sensor, seen, clocks, facts),
        facts=facts,
    )


def revolution_seconds(seen: Evidence, sensor: Identified) -> float:
    """One revolution's duration from the block step and the model's timing (its first variant when it has several)."""
    return 360.0 / seen.azimuth_step_deg * sensor.model.azimuth_s[0] if math.isfinite(seen.azimuth_step_deg) else 0.1


def rmc(line: str) -> dict | None:
    """A position packet's sentence decoded (sim.nmea.parse) if it is an RMC with a good checksum and a date, else None."""
    try:
        fields = nmea.parse(line)
    except ValueError:
        return None
    return fields if fields["type"] == "RMC" and fields.get("date") is not None else None


def epoch_ns(fields: dict) -> int:
    """The UTC time of a decoded RMC (its date and time of day), ns since the Unix epoch."""
    day = fields["date"]
    return unix_ns(datetime(day.year, day.month, day.day, tzinfo=UTC)) + round(fields["seconds_of_day"] * 1e9)


def packets(path: Path, patch: tuple[int, int] | None) -> Iterator[Packet | tuple[int, int, str]]:
    """Data packets (their factory bytes set to `patch` when given) and the position packets' (sensor ns, capture ns, sentence)."""
    clock = SensorClock()
    for datagram in capture.datagrams(path):
        payload = datagram.payload
        if len(payload) == DATA_BYTES:
            sensor = clock.ns(int.from_bytes(payload[STAMP_AT : STAMP_AT + 4], "little"), datagram.ns)
            if patch is not None and (payload[-2], payload[-1]) != patch:
                payload = payload[:-2] + bytes(patch)
            yield Packet(sensor, datagram.ns / 1e9, payload)
        elif len(payload) == POSITION_BYTES:
            telemetry = vd.TelemetryPacket(np.frombuffer(payload, np.uint8))
            yield clock.ns(telemetry.usec_since_toh, datagram.ns), datagram.ns, telemetry.nmea_sentence.strip()


def factory_patch(seen: Evidence, sensor: Identified) -> tuple[int, int] | None:
    """The factory bytes velodyne_decoder must see to decode as the identified model (None: the packets' own will do)."""
    mode = seen.return_mode if seen.return_mode in (0x37, 0x38, DUAL) else sensor.factory_bytes[0]
    wanted = (mode, sensor.model.product_id)
    return None if wanted == (seen.return_mode, seen.product_id) else wanted


def events(path: Path, geo: Geo, cut_deg: float, sensor: Identified, seen: Evidence, clocks: Clocks, facts: dict) -> Iterator[Event]:
    """Scans and fixes in time order, decoded lazily; whole and partial revolutions counted into `facts`."""
    decoder = vd.ScanDecoder(sensor.model.decoder_config())
    cutter, order, latest = Cutter(cut_deg, seen.packet_s * 1e9), TimeOrder(), ""
    for item in packets(path, factory_patch(seen, sensor)):
        if isinstance(item, Packet):
            now = item.sensor_ns
            done = cutter.add(item)
            if done is not None:
                keep(done, order, decoder, sensor, seen.dual, clocks, geo, facts)
        else:
            now, arrived, line = item
            if line and line != latest and (fields := rmc(line)) is not None:
                stamp = geo.seconds(epoch_ns(fields))
                order.add(RecordedFix(stamp, fixes.from_nmea(stamp, [line], geo), (line,)))
            latest = line or latest
        yield from order.release(geo.seconds(clocks.utc_ns(now) - clocks.lag_ns))
    done = cutter.finish()
    if done is not None:
        keep(done, order, decoder, sensor, seen.dual, clocks, geo, facts)
    yield from order.rest()


def keep(revolution: Revolution, order: TimeOrder, decoder, sensor: Identified, dual: bool, clocks: Clocks, geo: Geo, facts: dict) -> None:
    """Queue a whole revolution's scan; count it, or the partial one dropped."""
    facts["revolutions" if revolution.whole else "partial_revolutions_dropped"] += 1
    if revolution.whole:
        order.add(scan_event(decoder, revolution, sensor, dual, clocks, geo))


def scan_event(decoder: vd.ScanDecoder, revolution: Revolution, sensor: Identified, dual: bool, clocks: Clocks, geo: Geo) -> ScanEvent:
    """A whole revolution decoded: a scan at its first packet's time on the timeline, points timed since it on the sensor's clock."""
    start = revolution.packets[0].sensor_ns
    batch = vd.PacketVector()
    for packet in revolution.packets:
        batch.append(vd.VelodynePacket(TimePair(packet.capture_s, (packet.sensor_ns - start) / 1e9), packet.payload))
    _, points = decoder.decode(batch, True)
    points = points[(points["return_type"] & STRONGEST_RETURN) > 0] if dual else points
    out = np.zeros(len(points), POINT_DTYPE)
    for name in ("x", "y", "z", "intensity", "time"):
        out[name] = points[name]
    out["ring"] = sensor.model.laser_of_ring[points["ring"]]
    t = geo.seconds(clocks.utc_ns(start))
    return ScanEvent(t, Scan(t, out))
