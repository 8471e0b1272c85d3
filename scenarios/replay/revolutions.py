"""A Velodyne data-packet stream cut into revolutions, each marked whole or partial.

A revolution ends with the packet whose last block passes the cut azimuth (the scenario's lidar start, clockwise
as the packets count it), whole packets as velodyne_decoder's own batcher cuts them, so an exported run's
revolutions come back as they were written and each revolution of a stream holds one turn, give or take the
part of a packet that the next one holds less or more. It is whole when it starts where the previous one ended
and ends by passing the cut; the capture's first revolution is whole only when the capture starts at the cut
(its first packet holds it). The first and last revolutions of a capture, which starts and ends anywhere, and
both sides of a lost stretch of packets (a gap of more than GAP_PACKETS packet times on the sensor's clock) are
partial: a replay drops them, since a partial revolution's few points would make a scan gate's reference that
refuses every whole scan after it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from scenarios.replay.velodyne import BLOCKS

FULL_TURN = 36000
GAP_PACKETS = 2.5


@dataclass(frozen=True)
class Packet:
    """A data packet with its time on the sensor's clock (ns) and on the capture's (s, as velodyne_decoder takes it)."""

    sensor_ns: int
    capture_s: float
    payload: bytes

    @property
    def azimuths(self) -> np.ndarray:
        """The blocks' azimuths, 0.01 deg (each 100-byte block: flag, azimuth, 32 returns)."""
        return np.frombuffer(self.payload, "<u2", count=BLOCKS * 50)[1::50].astype(np.int64)


@dataclass
class Revolution:
    """Consecutive packets of one turn, and whether they are a whole one."""

    packets: list[Packet] = field(default_factory=list)
    whole: bool = False


class Cutter:
    """add(packet) -> the revolution it completes (or that a gap before it ended), else None; finish() -> the last one."""

    def __init__(self, cut_deg: float, packet_ns: float) -> None:
        self._cut = round(cut_deg * 100) % FULL_TURN
        self._gap_ns = GAP_PACKETS * packet_ns
        self._current = Revolution()
        self._coverage = 0
        self._clean = False  # the current revolution started where the previous one ended (or at the cut)

    def add(self, packet: Packet) -> Revolution | None:
        ended = None
        current = self._current
        if current.packets and packet.sensor_ns - current.packets[-1].sensor_ns > self._gap_ns:
            ended = self._close(whole=False)
            current = self._current
        azimuths = packet.azimuths
        if not current.packets and not self._clean:
            span = (int(azimuths[-1]) - int(azimuths[0])) % FULL_TURN
            self._clean = (int(azimuths[0]) - self._cut) % FULL_TURN <= span  # the capture (or gap) starts at the cut
        current.packets.append(packet)
        coverage = (int(azimuths[-1]) - self._cut) % FULL_TURN
        crossed = self._coverage > FULL_TURN // 2 and self._coverage > coverage
        self._coverage = coverage
        if crossed:
            return self._close(whole=self._clean, clean_next=True)
        return ended

    def finish(self) -> Revolution | None:
        """The revolution being collected when the stream ended: partial."""
        return self._close(whole=False) if self._current.packets else None

    def _close(self, whole: bool, clean_next: bool = False) -> Revolution:
        """End the current revolution and start the next (clean when it follows a passing of the cut)."""
        done, self._current, self._coverage, self._clean = self._current, Revolution(), 0, clean_next
        done.whole = whole
        return done
