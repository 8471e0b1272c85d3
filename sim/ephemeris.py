"""Broadcast ephemerides from a RINEX 3 navigation file: satellite ECEF positions of GPS, GLONASS, Galileo and BeiDou.

Read (RINEX 3.03-3.05, IGS/RTCM "RINEX The Receiver Independent Exchange Format" 3.04 Table A8-A11): each system's
broadcast orbit records. Positions:
- GPS, Galileo, BeiDou: the Keplerian elements with harmonic corrections, IS-GPS-200N Table 20-IV; Galileo OS SIS
  ICD 2.1 5.1.1 (its own mu); BeiDou BDS-SIS-ICD-B1I-3.0 5.2.4.12 (CGCS2000 mu and Earth rate; the GEO satellites,
  PRN 1-5 and 59-63, computed in an inertial-like frame and rotated by -5 deg about x and the Earth rate about z).
- GLONASS: the broadcast PZ-90 state vector (position, velocity, luni-solar acceleration) at tb, integrated with
  4th-order Runge-Kutta under the central field, J2 and the Earth's rotation, GLONASS ICD 5.1 (2008) A.3.1.2, steps
  of at most 60 s (as RTKLIB ephemeris.c glorbit). PZ-90.11 and WGS-84 agree to centimetres (no transformation).

Times inside are GPS seconds (since 1980-01-06 00:00:00 GPST). Galileo system time is taken as GPS time (they differ
by nanoseconds, the header's GPGA), BeiDou time is GPS time less 14 s, GLONASS records are in UTC (the header's leap
seconds give GPS time). A satellite is served at time t by its healthy record nearest in time within that system's
validity (`MAX_AGE_S`), else not at all, as a receiver without a current ephemeris does not use the satellite.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

GPS_EPOCH = datetime(1980, 1, 6, tzinfo=UTC)
WEEK_S = 604_800.0
BDT_WEEK_OFFSET = 1356
"""BeiDou week 0 began at GPS week 1356 (2006-01-01); BDT = GPST - 14 s (BDS-SIS-ICD-B1I-3.0 4.2)."""
BDT_MINUS_GPST_S = -14.0

SYSTEMS = {"G": "GPS", "R": "GLONASS", "E": "GALILEO", "C": "BEIDOU"}
"""RINEX system letter -> the name a scenario's `[gnss] constellations` uses."""
MU = {"G": 3.986005e14, "E": 3.986004418e14, "C": 3.986004418e14}
"""Gravitational parameter each system's broadcast elements assume, m^3/s^2 (IS-GPS-200N 20.3.3.4.3; Galileo OS SIS ICD
5.1.1; BDS-SIS-ICD-B1I-3.0 5.2.4.11)."""
EARTH_RATE = {"G": 7.2921151467e-5, "E": 7.2921151467e-5, "C": 7.292115e-5, "R": 7.292115e-5}
"""Earth rotation rate each system's ICD uses, rad/s (GLONASS ICD 5.1 3.1.3)."""
MAX_AGE_S = {"G": 7200.0, "R": 1800.0, "E": 14400.0, "C": 21600.0}
"""How far from its reference time a record is used, s: GPS half its 4 h curve fit interval (IS-GPS-200N 20.3.4.4; a
record's own fit interval field overrides), the others as RTKLIB 2.4.3 (rtklib.h MAXDTOE_GLO, MAXDTOE_GAL,
MAXDTOE_CMP), receivers' practice."""
SWITCH_GUARD_S = 1e-6
"""Within this of a switch time (Ephemeris._current) the record choice is made afresh, not taken from the interval's: a
midpoint of two reference times can round by a few 1e-7 s at GPS seconds of 1.4e9."""
GLO_MU = 3.9860044e14
GLO_AE = 6378136.0
GLO_J2 = 1082625.75e-9
"""GLONASS ICD 5.1 (2008) 3.1.3: PZ-90 gravitational parameter, equatorial radius (m) and second zonal harmonic."""
GLO_STEP_S = 60.0
BEIDOU_GEO = frozenset({1, 2, 3, 4, 5, 59, 60, 61, 62, 63})
"""BeiDou PRNs of geostationary satellites (BDS-SIS-ICD-B1I-3.0 5.2.4.12, note 1)."""
_EPOCH_COLUMNS = ((4, 8), (9, 11), (12, 14), (15, 17), (18, 20), (21, 23))
"""Columns of year, month, day, hour, minute, second on a record's first line."""
_LINES = {"G": 8, "E": 8, "C": 8, "J": 8, "I": 8, "R": 4, "S": 4}


class EphemerisError(ValueError):
    """A navigation file that cannot be read, or a time it does not cover."""


def gps_seconds(utc: datetime, leap_seconds: int) -> float:
    """GPS seconds of a UTC time (GPST = UTC + leap seconds)."""
    return (utc - GPS_EPOCH).total_seconds() + leap_seconds


def utc_of(gps_s: float, leap_seconds: int) -> datetime:
    """The UTC time of GPS seconds."""
    return GPS_EPOCH + timedelta(seconds=gps_s - leap_seconds)


@dataclass(frozen=True)
class Satellites:
    """Broadcast records of one system, one row per record: satellite number, reference time (GPS s), and the values."""

    letter: str
    prn: np.ndarray
    ref_s: np.ndarray
    max_age_s: np.ndarray
    healthy: np.ndarray
    values: np.ndarray
    """Keplerian systems: the 28 RINEX orbit fields after the clock (IODE, Crs, dn, M0, Cuc, e, Cus, sqrtA, toe, Cic,
    Omega0, Cis, i0, Crc, omega, Omegadot, IDOT, ...); GLONASS: x, y, z (m), vx, vy, vz (m/s), ax, ay, az (m/s^2)."""
    nodes: np.ndarray | None = None
    """GLONASS only: each record's state integrated once to every GLO_STEP_S node of its validity, (records, 2 K + 1, 6)
    for K steps either side: a position at any time is then one short step from its nearest node (glonass_positions_from)."""


@dataclass(frozen=True)
class Ephemeris:
    """A RINEX 3 navigation file's healthy GPS, GLONASS, Galileo and BeiDou records."""

    name: str
    leap_seconds: int
    systems: dict[str, Satellites]
    _switches: dict[str, np.ndarray] = field(default_factory=dict, init=False, repr=False, compare=False)
    _chosen: dict[tuple[str, int, bytes], np.ndarray] = field(default_factory=dict, init=False, repr=False, compare=False)

    def satellites(self, letters: str) -> list[tuple[str, int]]:
        """(system letter, PRN) of every satellite of the given systems with at least one healthy record, sorted."""
        return [(s, int(p)) for s in letters if s in self.systems for p in np.unique(self.systems[s].prn[self.systems[s].healthy])]

    def span_s(self, letters: str) -> tuple[float, float]:
        """GPS seconds from the latest start to the earliest end of the given systems' validity (per system the median over its
        satellites of the start of their first healthy record's validity and the end of their last's: one satellite's stray
        early or late upload does not stretch the span)."""
        missing = [SYSTEMS[s] for s in letters if s not in self.systems or not self.systems[s].healthy.any()]
        if missing:
            raise EphemerisError(f"ephemeris file {self.name} has no healthy records of {', '.join(missing)}")
        present = [self.systems[s] for s in letters]
        start = max(_median_per_satellite(s, s.ref_s - s.max_age_s, np.min) for s in present)
        end = min(_median_per_satellite(s, s.ref_s + s.max_age_s, np.max) for s in present)
        return start, end

    def positions(self, letter: str, prn: np.ndarray, t_gps: float) -> np.ndarray:
        """(N, 3) ECEF positions (m) at GPS seconds t of the given satellites of one system; NaN rows where none is current."""
        out = np.full((len(prn), 3), np.nan)
        sats = self.systems.get(letter)
        if sats is None or not len(prn):
            return out
        want = self._current(letter, sats, prn, t_gps)
        have = want >= 0
        if not have.any():
            return out
        records = want[have]
        dt = t_gps - sats.ref_s[records]
        if letter == "R":
            out[have] = glonass_positions_from(sats.nodes, sats.values[records, 6:9], records, dt)
        else:
            out[have] = kepler_positions(letter, sats.prn[records], sats.values[records], dt)
        return out

    def _current(self, letter: str, sats: Satellites, prn: np.ndarray, t_gps: float) -> np.ndarray:
        """Per satellite of `prn`, the row of its usable record nearest in time at t (-1: none). The choice changes only at
        a record's validity edges and half-way between two of a satellite's reference times, so it is computed once per
        interval between those switch times (and afresh within SWITCH_GUARD_S of one)."""
        if letter not in self._switches:
            self._switches[letter] = _switch_times(sats)
        switches = self._switches[letter]
        i = int(np.searchsorted(switches, t_gps))
        beside = switches[max(i - 1, 0) : i + 1]  # the switch times either side of t
        if len(beside) and float(np.min(np.abs(beside - t_gps))) <= SWITCH_GUARD_S:
            return _nearest_usable(sats, prn, t_gps)
        key = (letter, i, prn.tobytes())
        if key not in self._chosen:
            self._chosen[key] = _nearest_usable(sats, prn, t_gps)
        return self._chosen[key]


def _nearest_usable(sats: Satellites, prn: np.ndarray, t_gps: float) -> np.ndarray:
    """Per satellite of `prn`, the row of its healthy record nearest in time among those valid at t (-1: none)."""
    age = np.abs(t_gps - sats.ref_s)
    usable = (age <= sats.max_age_s) & sats.healthy
    order = np.lexsort((np.where(usable, age, np.inf), sats.prn))
    first = order[np.r_[True, sats.prn[order][1:] != sats.prn[order][:-1]]]
    first = first[usable[first]]
    rows = dict(zip(sats.prn[first].tolist(), first.tolist(), strict=True))
    return np.array([rows.get(int(p), -1) for p in prn], dtype=np.int64)


def _switch_times(sats: Satellites) -> np.ndarray:
    """Sorted times at which `_nearest_usable` may change its choice: every record's validity edges and the midpoints
    between any two reference times of one satellite."""
    edges = [sats.ref_s - sats.max_age_s, sats.ref_s + sats.max_age_s]
    for number in np.unique(sats.prn):
        ref = sats.ref_s[sats.prn == number]
        edges.append(((ref[:, None] + ref[None, :]) / 2.0).ravel())
    return np.unique(np.concatenate(edges))


def _median_per_satellite(sats: Satellites, times: np.ndarray, pick) -> float:
    """The median over satellites of pick(times of the satellite's healthy records)."""
    return float(np.median([pick(times[(sats.prn == prn) & sats.healthy]) for prn in np.unique(sats.prn[sats.healthy])]))


def kepler_positions(letter: str, prn: np.ndarray, v: np.ndarray, tk: np.ndarray) -> np.ndarray:
    """ECEF positions (N, 3) from broadcast Keplerian elements `v` (Satellites.values rows) tk seconds after toe."""
    crs, dn, m0, cuc, e, cus, sqrt_a, toe, cic, omega0, cis, i0, crc, omega, omega_dot, idot = (v[:, k] for k in range(1, 17))
    mu, we = MU[letter], EARTH_RATE[letter]
    a = sqrt_a**2
    mean = m0 + (np.sqrt(mu / a**3) + dn) * tk
    ecc = mean.copy()
    for _ in range(10):  # Kepler's equation by Newton's method: converges to 1e-15 rad in a few steps for e < 0.1
        ecc = ecc - (ecc - e * np.sin(ecc) - mean) / (1.0 - e * np.cos(ecc))
    nu = np.arctan2(np.sqrt(1.0 - e * e) * np.sin(ecc), np.cos(ecc) - e)
    phi = nu + omega
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    u = phi + cus * s2 + cuc * c2
    r = a * (1.0 - e * np.cos(ecc)) + crs * s2 + crc * c2
    inc = i0 + cis * s2 + cic * c2 + idot * tk
    x_orb, y_orb = r * np.cos(u), r * np.sin(u)
    geo = np.isin(prn, list(BEIDOU_GEO)) if letter == "C" else np.zeros(len(prn), dtype=bool)
    node = omega0 + np.where(geo, omega_dot * tk, (omega_dot - we) * tk) - we * toe
    cn, sn, ci, si = np.cos(node), np.sin(node), np.cos(inc), np.sin(inc)
    xyz = np.stack([x_orb * cn - y_orb * ci * sn, x_orb * sn + y_orb * ci * cn, y_orb * si], axis=1)
    if geo.any():  # BDS ICD 5.2.4.12: R_z(we tk) R_x(-5 deg) of the positions in the GEO's inertial-like frame
        g = xyz[geo]
        c5, s5 = np.cos(np.deg2rad(-5.0)), np.sin(np.deg2rad(-5.0))
        y1, z1 = c5 * g[:, 1] + s5 * g[:, 2], -s5 * g[:, 1] + c5 * g[:, 2]
        ang = we * tk[geo]
        cz, sz = np.cos(ang), np.sin(ang)
        xyz[geo] = np.stack([cz * g[:, 0] + sz * y1, -sz * g[:, 0] + cz * y1, z1], axis=1)
    return xyz


def _glonass_rates(state: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """d/dt of (x, y, z, vx, vy, vz) in the rotating PZ-90 frame (GLONASS ICD 5.1 A.3.1.2)."""
    pos, vel = state[:, :3], state[:, 3:]
    r2 = np.einsum("ij,ij->i", pos, pos)
    r = np.sqrt(r2)
    r3 = r2 * r
    a = 1.5 * GLO_J2 * GLO_MU * GLO_AE**2 / (r2 * r3)
    b = 5.0 * pos[:, 2] ** 2 / r2
    c = -GLO_MU / r3 - a * (1.0 - b)
    w = EARTH_RATE["R"]
    acc = np.stack(
        [
            (c + w * w) * pos[:, 0] + 2.0 * w * vel[:, 1],
            (c + w * w) * pos[:, 1] - 2.0 * w * vel[:, 0],
            (c - 2.0 * a) * pos[:, 2],
        ],
        axis=1,
    )
    return np.concatenate([vel, acc + accel], axis=1)


def _rk4(state: np.ndarray, accel: np.ndarray, h: np.ndarray | float) -> np.ndarray:
    """One 4th-order Runge-Kutta step of h seconds (per row) of GLONASS states."""
    h = np.broadcast_to(np.asarray(h, dtype=float), (len(state),))[:, None]
    k1 = _glonass_rates(state, accel)
    k2 = _glonass_rates(state + 0.5 * h * k1, accel)
    k3 = _glonass_rates(state + 0.5 * h * k2, accel)
    k4 = _glonass_rates(state + h * k3, accel)
    return state + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def glonass_positions(v: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """ECEF positions (N, 3) from GLONASS state vectors `v` (x, y, z, vx, vy, vz, ax, ay, az) integrated dt seconds (RK4)."""
    state, accel = v[:, :6].copy(), v[:, 6:9]
    steps = max(1, int(np.ceil(np.max(np.abs(dt)) / GLO_STEP_S)))
    h = np.asarray(dt, dtype=float) / steps
    for _ in range(steps):
        state = _rk4(state, accel, h)
    return state[:, :3]


def glonass_nodes(v: np.ndarray, max_age_s: float) -> np.ndarray:
    """Each state of `v` integrated to every GLO_STEP_S node within +-max_age_s: (N, 2 K + 1, 6), node K at the record."""
    k = int(np.ceil(max_age_s / GLO_STEP_S))
    out = np.empty((len(v), 2 * k + 1, 6))
    out[:, k] = v[:, :6]
    for direction in (1.0, -1.0):
        state = v[:, :6].copy()
        for j in range(1, k + 1):
            state = _rk4(state, v[:, 6:9], direction * GLO_STEP_S)
            out[:, k + int(direction) * j] = state
    return out


def glonass_positions_from(nodes: np.ndarray | None, accel: np.ndarray, records: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """ECEF positions (N, 3) of GLONASS records dt seconds from their reference times: one RK4 step (at most half a node
    spacing) from the nearest precomputed node (glonass_nodes), the same integration as glonass_positions to millimetres."""
    if nodes is None:
        raise ValueError("GLONASS records without integration nodes")
    k = (nodes.shape[1] - 1) // 2
    node = np.clip(np.rint(dt / GLO_STEP_S).astype(int), -k, k)
    start = nodes[records, k + node]
    return _rk4(start, accel, dt - node * GLO_STEP_S)[:, :3]


def _float(text: str) -> float:
    text = text.strip().replace("D", "E").replace("d", "e")
    return float(text) if text else 0.0


def _fields(lines: list[str]) -> list[float]:
    """The numbers of one record after its epoch: 3 on the first line, 4 on each following (19 characters each)."""
    out = [_float(lines[0][23 + 19 * k : 42 + 19 * k]) for k in range(3)]
    for line in lines[1:]:
        out += [_float(line[4 + 19 * k : 23 + 19 * k]) for k in range(4)]
    return out


def read(path: str | Path) -> Ephemeris:
    """Parse a RINEX 3 navigation file (mixed or single-system); EphemerisError naming the file on anything it cannot read."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="ascii", errors="replace").splitlines()
    except OSError as exc:
        raise EphemerisError(f"ephemeris file {path}: {exc.strerror or exc}") from None
    if not lines or "RINEX VERSION" not in lines[0] or not lines[0][:9].strip().startswith("3") or lines[0][20] != "N":
        raise EphemerisError(f"ephemeris file {path} is not a RINEX 3 navigation file")
    version = float(lines[0][:9])
    leap = 18
    body = 0
    for k, line in enumerate(lines):
        if "LEAP SECONDS" in line[60:]:
            leap = int(line[:6])
        if "END OF HEADER" in line[60:]:
            body = k + 1
            break
    else:
        raise EphemerisError(f"ephemeris file {path} has no END OF HEADER")
    rows: dict[str, list[tuple[int, float, float, bool, list[float]]]] = {s: [] for s in SYSTEMS}
    k = body
    try:
        while k < len(lines):
            head = lines[k]
            if not head.strip():
                k += 1
                continue
            letter = head[0]
            n = _LINES[letter] + (1 if letter == "R" and version >= 3.05 else 0)
            record = [line.ljust(80) for line in lines[k : k + n]]
            k += n
            if letter not in SYSTEMS:
                continue
            prn = int(head[1:3])
            year, month, day, hour, minute, second = (int(head[a:b]) for a, b in _EPOCH_COLUMNS)
            epoch = datetime(year, month, day, hour, minute, second, tzinfo=UTC)
            f = _fields(record)
            rows[letter].append(_record(letter, prn, epoch, f, leap))
    except (KeyError, ValueError, IndexError):
        raise EphemerisError(f"ephemeris file {path}: cannot read the record at line {k + 1}") from None
    systems = {}
    for letter, recs in rows.items():
        if recs:
            columns = [np.array(column) for column in zip(*recs, strict=True)]
            nodes = glonass_nodes(columns[4], float(columns[2].max())) if letter == "R" else None
            systems[letter] = Satellites(letter, columns[0], columns[1], columns[2], columns[3].astype(bool), columns[4], nodes)
    return Ephemeris(path.name, leap, systems)


def _record(letter: str, prn: int, epoch: datetime, f: list[float], leap: int) -> tuple[int, float, float, bool, list[float]]:
    """(prn, reference GPS seconds, max age, healthy, values) of one record's fields `f`."""
    max_age = MAX_AGE_S[letter]
    if letter == "R":
        health = f[6]
        values = [f[3], f[7], f[11], f[4], f[8], f[12], f[5], f[9], f[13]]
        ref = gps_seconds(epoch, leap)
        return prn, ref, max_age, health == 0, [x * 1e3 for x in values]
    orbit = f[3:]
    toe, week, health = orbit[8], orbit[18], orbit[21]
    if letter == "C":
        ref = (week + BDT_WEEK_OFFSET) * WEEK_S + toe - BDT_MINUS_GPST_S
    else:
        ref = week * WEEK_S + toe
    if letter == "G" and len(orbit) > 25 and orbit[25] > 4.0:
        max_age = orbit[25] * 1800.0  # fit interval in hours (RINEX 3): half of it either side of toe
    values = (orbit + [0.0] * 28)[:28]
    return prn, ref, max_age, health == 0, values
