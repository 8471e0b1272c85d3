"""A libpcap capture read record by record: each UDP datagram's capture time (integer nanoseconds since the Unix epoch,
never float seconds), ports and payload; a file that is no libpcap capture, or that is cut short inside a record,
is a one-line ValueError.

Record framing is read here (the file header's magic number gives byte order and microsecond or nanosecond
times; each record header its time and captured length), so a truncated last record is caught, which
dpkt's reader hands back short without a word. The link layers a capture of a Velodyne holds: Ethernet
(with or without 802.1Q tags), Linux cooked (SLL, SLL2), raw IP and BSD loopback, parsed by dpkt; a plain
Ethernet II + IPv4 + UDP frame, nearly every one, is cut by its fixed offsets instead (the same bytes,
several times faster). pcapng files are refused with the command that converts them.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import dpkt

MAGIC = {
    b"\xd4\xc3\xb2\xa1": ("<", 1000),
    b"\xa1\xb2\xc3\xd4": (">", 1000),
    b"\x4d\x3c\xb2\xa1": ("<", 1),
    b"\xa1\xb2\x3c\x4d": (">", 1),
}
"""libpcap magic numbers: byte order and nanoseconds per unit of the record's sub-second field."""
PCAPNG = b"\x0a\x0d\x0d\x0a"
FILE_HEADER = 24
RECORD_HEADER = 16
ETHERNET, NULL, RAW, SLL, SLL2, IPV4 = 1, 0, 101, 113, 276, 228
LINK_NAMES = {ETHERNET: "Ethernet", NULL: "loopback", RAW: "raw IP", SLL: "Linux cooked", SLL2: "Linux cooked v2", IPV4: "raw IPv4"}


@dataclass(frozen=True)
class Datagram:
    """One UDP datagram of the capture: capture time (ns since the Unix epoch), destination port and payload."""

    ns: int
    port: int
    payload: bytes


def is_capture(path: Path) -> bool:
    """Whether the file starts like a libpcap or pcapng capture."""
    with path.open("rb") as handle:
        head = handle.read(4)
    return head in MAGIC or head == PCAPNG


def datagrams(path: str | Path) -> Iterator[Datagram]:
    """Every UDP datagram in capture order; ValueError (one line) for a file that is no libpcap capture or is cut short."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such capture")
    with path.open("rb") as handle:
        header = handle.read(FILE_HEADER)
        if header[:4] == PCAPNG:
            raise ValueError(f"{path}: a pcapng capture; convert it to pcap first (editcap -F pcap {path.name} out.pcap)")
        if len(header) < FILE_HEADER or header[:4] not in MAGIC:
            raise ValueError(f"{path}: not a libpcap capture (no pcap file header)")
        order, unit_ns = MAGIC[header[:4]]
        link = struct.unpack(order + "I", header[20:24])[0] & 0xFFFF
        if link not in LINK_NAMES:
            raise ValueError(f"{path}: link type {link} is not one a Velodyne capture uses ({', '.join(LINK_NAMES.values())})")
        record = struct.Struct(order + "IIII")
        offset, index = FILE_HEADER, 0
        while head := handle.read(RECORD_HEADER):
            if len(head) < RECORD_HEADER:
                raise ValueError(f"{path}: truncated: record {index} at byte {offset} is cut inside its header")
            seconds, fraction, length, _ = record.unpack(head)
            frame = handle.read(length)
            if len(frame) < length:
                raise ValueError(f"{path}: truncated: record {index} at byte {offset} holds {len(frame)} of its {length} bytes")
            udp = udp_of(frame, link)
            if udp is not None:
                yield Datagram(seconds * 1_000_000_000 + fraction * unit_ns, *udp)
            offset += RECORD_HEADER + length
            index += 1


def udp_of(frame: bytes, link: int) -> tuple[int, bytes] | None:
    """(destination port, payload) of a frame holding an unfragmented IPv4 or IPv6 UDP datagram, else None."""
    if link == ETHERNET and len(frame) >= 42 and frame[12:14] == b"\x08\x00" and frame[23] == 17 and not frame[20] & 0x3F and not frame[21]:
        start = 14 + (frame[14] & 0x0F) * 4
        size = int.from_bytes(frame[start + 4 : start + 6], "big")
        return int.from_bytes(frame[start + 2 : start + 4], "big"), frame[start + 8 : start + size]
    try:
        packet = {
            ETHERNET: dpkt.ethernet.Ethernet,
            SLL: dpkt.sll.SLL,
            SLL2: dpkt.sll2.SLL2,
            NULL: dpkt.loopback.Loopback,
            RAW: raw_ip,
            IPV4: dpkt.ip.IP,
        }[link](frame)
    except (dpkt.UnpackError, ValueError):
        return None
    ip = packet if isinstance(packet, dpkt.ip.IP | dpkt.ip6.IP6) else getattr(packet, "data", None)
    if isinstance(ip, dpkt.ip.IP) and (ip.offset or ip.mf):
        return None  # a fragment: Velodyne datagrams are never fragmented
    udp = getattr(ip, "data", None)
    return (udp.dport, bytes(udp.data)) if isinstance(udp, dpkt.udp.UDP) else None


def raw_ip(frame: bytes):
    """An IPv4 or IPv6 packet by its version nibble (link type RAW)."""
    return dpkt.ip6.IP6(frame) if frame and frame[0] >> 4 == 6 else dpkt.ip.IP(frame)
