"""Which constellation and signal an NMEA satellite number belongs to, as real receivers number them.

NMEA 0183 numbers satellites per talker and, before version 4.10, in one range for all systems;
receivers differ. The rules (gpsd's, drivers/driver_nmea0183.c nmeaid_to_prn and include/gps.h
satellite_t at commit 46977faa, ntpsec/gpsd; https://github.com/mvglasow/satstat/wiki/NMEA-IDs):

- NMEA 4.10 system id (GSA's last field, and the talker of a GSV): 1 GPS (also SBAS 33-64 and
  152-158, QZSS 193-202), 2 GLONASS, 3 Galileo, 4 BeiDou, 5 QZSS, 6 NavIC.
- A single-system talker (GL, GA, GB/BD, GQ/QZ, GI) names the system of the satellites it lists.
- Otherwise (GP, GN, others: chartplotters put GLONASS in GPGSV) the number's range: 1-32 GPS,
  33-64 SBAS (PRN = number + 87), 65-96 GLONASS (slot = number - 64), 120-158 SBAS, 173-182 IMES,
  193-199 QZSS (u-blox), 201-237 BeiDou (SiRF, Quectel), 301-336 Galileo, 401-437 BeiDou (u-blox).
Within its system a satellite is then known by its own number (`svid`: GPS PRN, GLONASS slot,
Galileo and BeiDou SV id, QZSS 1-10, SBAS PRN 120-158), whatever range the receiver used.

Signals: the NMEA 4.10/4.11 signal id at the end of a GSV (hexadecimal), per system (gps.h's
table); 0 or no id means the receiver does not say, taken as the system's civil L1-band signal,
the only one a receiver without the field tracks.
"""

from __future__ import annotations

GPS, GLONASS, GALILEO, BEIDOU, QZSS, NAVIC, SBAS, IMES, UNKNOWN = "GPS", "GLONASS", "Galileo", "BeiDou", "QZSS", "NavIC", "SBAS", "IMES", "unknown"

SYSTEM_IDS = {1: GPS, 2: GLONASS, 3: GALILEO, 4: BEIDOU, 5: QZSS, 6: NAVIC}
"""NMEA 4.10/4.11 GNSS system id -> system."""
TALKERS = {"GL": GLONASS, "GA": GALILEO, "GB": BEIDOU, "BD": BEIDOU, "GQ": QZSS, "QZ": QZSS, "GI": NAVIC}
"""Talkers that speak for one system only (GP and GN may list several: numbered by range)."""
GNSS_TALKERS = frozenset({"GP", "GN", *TALKERS})
"""Talkers of satellite navigation receivers."""

SIGNALS = {
    GPS: {1: "L1 C/A", 2: "L1 P(Y)", 3: "L1C", 4: "L2 P(Y)", 5: "L2C-M", 6: "L2C-L", 7: "L5-I", 8: "L5-Q"},
    GLONASS: {1: "L1OF", 2: "L1P", 3: "L2OF", 4: "L2P"},
    GALILEO: {1: "E5a", 2: "E5b", 3: "E5a+b", 4: "E6-A", 5: "E6-BC", 6: "E1-A", 7: "E1-BC"},
    BEIDOU: {1: "B1I", 2: "B1Q", 3: "B1C", 5: "B2a", 8: "B3I", 11: "B2I"},
    QZSS: {1: "L1 C/A", 4: "L1S", 5: "L2C-M", 6: "L2C-L", 7: "L5-I", 8: "L5-Q"},
    NAVIC: {1: "L5 SPS"},
}
"""NMEA 4.11 signal ids per system (gpsd include/gps.h, satellite_t)."""
PRIMARY = {GPS: "L1 C/A", GLONASS: "L1OF", GALILEO: "E1-BC", BEIDOU: "B1I", QZSS: "L1 C/A", NAVIC: "L5 SPS", SBAS: "L1 C/A", IMES: "L1 C/A"}
"""The signal a receiver that gives no signal id tracks: each system's civil L1-band signal (L5 for NavIC)."""
BANDS = {
    "L1 C/A": "L1",
    "L1 P(Y)": "L1",
    "L1C": "L1",
    "L1S": "L1",
    "L1OF": "L1",
    "L1P": "L1",
    "E1-A": "L1",
    "E1-BC": "L1",
    "B1I": "L1",
    "B1Q": "L1",
    "B1C": "L1",
    "L2 P(Y)": "L2",
    "L2C-M": "L2",
    "L2C-L": "L2",
    "L2OF": "L2",
    "L2P": "L2",
    "B2I": "L2",
    "L5-I": "L5",
    "L5-Q": "L5",
    "E5a": "L5",
    "B2a": "L5",
    "L5 SPS": "L5",
    "E5b": "E5b",
    "E5a+b": "E5b",
    "E6-A": "E6",
    "E6-BC": "E6",
    "B3I": "E6",
}
"""Frequency band of each signal (L1 ~1575 MHz incl. GLONASS G1 and BeiDou B1; L2 ~1227 MHz incl. G2 and B2I;
L5 ~1176 MHz incl. E5a and B2a; E5b ~1207 MHz; E6 ~1278 MHz incl. B3)."""


def by_range(number: int) -> tuple[str, int]:
    """(system, svid) of a satellite number of a multi-system talker (GP, GN), by its range (module docstring)."""
    if 1 <= number <= 32:
        return GPS, number
    if 33 <= number <= 64:
        return SBAS, number + 87
    if 65 <= number <= 96:
        return GLONASS, number - 64
    if 120 <= number <= 158:
        return SBAS, number
    if 173 <= number <= 182:
        return IMES, number - 172
    if 193 <= number <= 199:
        return QZSS, number - 192
    if 201 <= number <= 237:
        return BEIDOU, number - 200
    if 301 <= number <= 336:
        return GALILEO, number - 300
    if 401 <= number <= 437:
        return BEIDOU, number - 400
    return UNKNOWN, number


GPSD_OFFSETS = {GPS: 0, SBAS: 0, GLONASS: 64, QZSS: 192, GALILEO: 300, BEIDOU: 400, NAVIC: 500}
"""gpsd's one numbering of all systems' satellites (include/gps.h satellite_t PRN: GLONASS 65-96, QZSS 193-202,
Galileo 301-336, BeiDou 401-463), which gpsd_client passes on in gps_msgs/GPSStatus."""


def gpsd_prn(system: str, svid: int) -> int:
    """A satellite's number in gpsd's numbering (GPSD_OFFSETS) from its system and number within it."""
    return svid + GPSD_OFFSETS.get(system, 0)


def in_system(system: str, number: int) -> tuple[str, int]:
    """(system, svid) of a satellite number a single system's talker or system id lists, in any of the ranges receivers use for it."""
    if system == GPS:
        return by_range(number)  # system id 1 also covers SBAS and QZSS (NMEA 4.10)
    offsets = {GLONASS: (64,), GALILEO: (100, 300), BEIDOU: (200, 400), QZSS: (192,), NAVIC: (500,)}.get(system, ())
    for offset in offsets:
        if offset < number <= offset + 99:
            return system, number - offset
    return system, number


def satellite(talker: str, number: int, system_id: int | None = None) -> tuple[str, int]:
    """(system, svid) of satellite `number` listed by `talker` (with a GSA's NMEA 4.10 system id, if any)."""
    if system_id in SYSTEM_IDS:
        return in_system(SYSTEM_IDS[system_id], number)
    if talker in TALKERS:
        return in_system(TALKERS[talker], number)
    return by_range(number)


def signal(system: str, signal_id: int | None) -> str:
    """The signal a GSV's NMEA 4.11 signal id names for `system` (the primary signal without one; 'id N' when unknown)."""
    if not signal_id:
        return PRIMARY.get(system, "")
    table = SIGNALS[GPS] if system in (SBAS, IMES) else SIGNALS.get(system, {})  # listed under GPS's system id, numbered as GPS's
    return table.get(signal_id, f"id {signal_id:X}")


def band(signal_name: str) -> str:
    """The frequency band of a signal name ('L1' for an unknown one: the band every receiver tracks)."""
    return BANDS.get(signal_name, "L1")
