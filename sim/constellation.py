"""The satellites a receiver tracks: GPS, GLONASS, Galileo and BeiDou from a real broadcast ephemeris file.

Positions come from the file's broadcast orbits (sim.ephemeris); a satellite without a current healthy record is not
served, as a receiver without its ephemeris does not use it. The shipped file (sim/data/NOTICE) holds the ephemerides
the IGS station ELKO (Elko, Nevada) logged on 2018-07-29 from 11:00 to 19:59 GPST; any RINEX 3 navigation file may
be named instead. Per system: the NMEA name and the signal a single-frequency receiver tracks, its C/N0 relative
to GPS L1 C/A, and its code noise relative to GPS L1 C/A.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Literal

import numpy as np

from sim import ephemeris
from sim.nmea import systems as nmea

System = Literal["GPS", "GLONASS", "GALILEO", "BEIDOU"]
DATA = Path(__file__).parent / "data"
DEFAULT_EPHEMERIS = "ELKO00USA_R_20182100000_01D_MN.rnx"
"""The shipped file (sim/data/NOTICE: source, licence, how it was cut)."""
LETTERS: dict[str, str] = {name: letter for letter, name in ephemeris.SYSTEMS.items()}
NMEA_SYSTEM = {"GPS": nmea.GPS, "GLONASS": nmea.GLONASS, "GALILEO": nmea.GALILEO, "BEIDOU": nmea.BEIDOU}
"""Config name -> sim.nmea.systems name (what SatelliteReport.system carries)."""
CN0_OFFSET_DB = {"GPS": 0.0, "GLONASS": -2.5, "GALILEO": 1.5, "BEIDOU": -4.5}
"""C/N0 of each system's L1-band civil signal relative to GPS L1 C/A, dB: the difference of the specified minimum
received powers, GPS L1 C/A -158.5 dBW (IS-GPS-200N Table 3-Va), GLONASS L1OF -161 dBW (GLONASS ICD 5.1, 2008,
3.3.1.6), Galileo E1 B+C -157 dBW (Galileo OS SIS ICD 2.1, 2.4.1), BeiDou B1I -163 dBW (BDS-SIS-ICD-B1I-3.0, 3.3);
the same priors as fusion.monitors.cn0.PRIOR_OFFSETS_DB."""
CODE_NOISE_SCALE = {"GPS": 1.0, "GLONASS": 2.0, "GALILEO": 1.0, "BEIDOU": 0.5}
"""White code noise relative to GPS L1 C/A at the same C/N0 and correlator spacing in chips: the delay-lock loop's
thermal noise scales with the chip length (Kaplan and Hegarty, Understanding GPS/GNSS, 3rd ed., 2017, eq. 8.54),
GLONASS L1OF 0.511 Mchip/s (twice GPS's chip), BeiDou B1I 2.046 Mchip/s (half); Galileo E1 BOC(1,1) at 1.023
Mchip/s taken as GPS (its sharper correlation peak would lower it: conservative)."""


def ephemeris_path(name: str) -> Path:
    """A shipped file's name (sim/data) or a path to a RINEX 3 navigation file."""
    shipped = DATA / name
    return shipped if shipped.is_file() else Path(name)


@functools.lru_cache(maxsize=4)
def _read(path: str, mtime_ns: int) -> ephemeris.Ephemeris:
    del mtime_ns  # part of the cache key only: a file rewritten in place is read again
    return ephemeris.read(path)


def load_ephemeris(name: str) -> ephemeris.Ephemeris:
    """The parsed file (cached per path and modification time: configs and receivers share one parse)."""
    path = ephemeris_path(name)
    try:
        mtime = path.stat().st_mtime_ns
    except OSError:
        raise ephemeris.EphemerisError(
            f"ephemeris file {name} not found (shipped: {', '.join(sorted(p.name for p in DATA.glob('*.rnx')))})"
        ) from None
    return _read(str(path), mtime)


def _iso(utc: datetime) -> str:
    return utc.astimezone(UTC).strftime("%Y-%m-%dT%H:%MZ")


@dataclass(frozen=True)
class Constellation:
    """Satellites of the chosen systems in an ephemeris file: per satellite its system (config name), number within
    its system (GPS PRN, GLONASS slot, Galileo/BeiDou SV id); positions at any UTC the file covers."""

    source: ephemeris.Ephemeris
    system: tuple[str, ...]
    prn: np.ndarray
    start_utc: datetime
    end_utc: datetime

    @classmethod
    def load(cls, name: str = DEFAULT_EPHEMERIS, systems: tuple[str, ...] = ("GPS",)) -> Constellation:
        """The satellites of `systems` in ephemeris file `name` (EphemerisError if it cannot be read or lacks them)."""
        source = load_ephemeris(name)
        letters = "".join(LETTERS[s] for s in systems)
        sats = source.satellites(letters)
        start, end = source.span_s(letters)
        return cls(
            source=source,
            system=tuple(ephemeris.SYSTEMS[letter] for letter, _ in sats),
            prn=np.array([p for _, p in sats], dtype=int),
            start_utc=ephemeris.utc_of(start, source.leap_seconds),
            end_utc=ephemeris.utc_of(end, source.leap_seconds),
        )

    def __len__(self) -> int:
        return len(self.prn)

    def check(self, utc: datetime, what: str = "gnss.epoch_utc") -> None:
        """EphemerisError naming `what` when utc is outside the span the file covers for these systems."""
        if utc.tzinfo is None:
            raise ephemeris.EphemerisError(f"{what} {utc.isoformat()} has no time zone (use UTC)")
        if not self.start_utc <= utc <= self.end_utc:
            raise ephemeris.EphemerisError(
                f"{what} {_iso(utc)} is outside the ephemeris file {self.source.name} (covers {_iso(self.start_utc)} to {_iso(self.end_utc)})"
            )

    @functools.cached_property
    def _groups(self) -> list[tuple[str, np.ndarray]]:
        names = np.array(self.system)
        return [(LETTERS[s], np.nonzero(names == s)[0]) for s in dict.fromkeys(self.system)]

    def ecef(self, utc: datetime) -> np.ndarray:
        """(N, 3) ECEF positions (m) at utc; NaN rows for satellites without a current healthy record."""
        self.check(utc, "gnss: time")
        t = ephemeris.gps_seconds(utc, self.source.leap_seconds)
        out = np.full((len(self), 3), np.nan)
        for letter, rows in self._groups:
            out[rows] = self.source.positions(letter, self.prn[rows], t)
        return out

    def per_satellite(self, table: dict[str, float]) -> np.ndarray:
        """A per-system table (CN0_OFFSET_DB, CODE_NOISE_SCALE) as one value per satellite."""
        return np.array([table[s] for s in self.system], dtype=float)
