"""GnssFix: what a GNSS receiver reports for one epoch, plus the simulator's exact truth."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.nmea import fix_sentences
from sim.nmea.systems import GPS, PRIMARY


@dataclass(frozen=True)
class SatelliteReport:
    """One satellite signal as the receiver reports it (NMEA GSV/GSA): its number in its system (prn: the GPS PRN,
    GLONASS slot, Galileo/BeiDou SV id), azimuth and elevation (deg), C/N0 (dB-Hz, 0 when not tracked), whether the
    fix used it, its system and signal (sim.nmea.systems' names; the simulated receiver tracks each system's civil
    L1-band signal, sim.nmea.systems.PRIMARY)."""

    prn: int
    az_deg: float
    el_deg: float
    snr: float
    used: bool
    system: str = GPS
    signal: str = PRIMARY[GPS]


@dataclass(frozen=True)
class SatelliteTruth:
    """Simulator truth for one satellite in view: line of sight or not, and its range bias (m); prn and system as its
    SatelliteReport's."""

    prn: int
    los: bool
    nlos: bool
    bias_m: float
    system: str = GPS


@dataclass(frozen=True)
class FixTruth:
    """Exact truth of a fix; read only by the bench's metrics, never by matchers or filters."""

    enu: np.ndarray
    error: np.ndarray
    sats: tuple[SatelliteTruth, ...] = ()
    open_sky_error: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    """The error this receiver would report under an open sky (same range errors and C/N0 draws, no
    blockage, reflections or forced faults): its nominal error, which no relative sensor (odometry)
    can observe. error - open_sky_error is what the environment added."""


@dataclass(frozen=True)
class GnssFix:
    """One receiver output epoch. quality follows NMEA GGA: 0 invalid, 1 GPS, 2 DGPS/SBAS, 4 RTK fixed, 5 RTK float,
    6 dead reckoning.

    enu is the reported antenna position in the world's ENU frame (NaN when quality is 0);
    lat/lon/alt are the same position in WGS-84 degrees and metres; utc is ISO 8601;
    speed_mps / course_deg are speed over ground and course (deg clockwise from north), NaN if unknown;
    correction_age_s and station_id the differential corrections' age (s) and reference station (GGA fields 13 and
    14), NaN and None when the fix is not differential.
    """

    stamp: float
    lat: float
    lon: float
    alt: float
    enu: np.ndarray
    quality: int
    num_sats: int
    hdop: float
    vdop: float
    pdop: float
    sats: tuple[SatelliteReport, ...] = ()
    utc: str = ""
    truth: FixTruth | None = field(default=None, compare=False, repr=False)
    speed_mps: float = float("nan")
    course_deg: float = float("nan")
    correction_age_s: float = float("nan")
    station_id: int | None = None
    systems: tuple[str, ...] = ()
    """The systems the receiver tracks (sim.nmea.systems names; NMEA talker GN when several); () when unknown: those of `sats`."""

    @property
    def valid(self) -> bool:
        return self.quality != 0

    def nmea(self) -> list[str]:
        """This epoch as NMEA 0183 sentences: GGA, RMC, GSA, GSV (see sim.nmea)."""
        return fix_sentences(self)
