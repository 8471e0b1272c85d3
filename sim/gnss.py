"""GnssReceiver: a GNSS receiver on the vessel, with ray-traced blackout and multipath over the world mesh.

Per epoch: satellite positions of the tracked constellations from a real broadcast ephemeris file
(sim.constellation, sim.ephemeris), azimuth/elevation from the antenna in the world's ENU frame, the elevation mask,
line of sight and facade reflections by ray casting (sim.visibility, sim.multipath), pseudoranges with the receiver
clock, elevation-dependent errors and NLOS/multipath biases (sim.pseudorange; each system's C/N0 and code noise
relative to GPS L1 C/A, sim.constellation), a weighted least-squares position with one receiver clock (sim.wls: the
systems' time offsets are broadcast, so the simulated ranges share one clock), and the receiver's own navigation
filter (sim.receiver_filter). Every fix carries the exact truth. All randomness comes from riverbench.rng.stream(seed, "gnss....").
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from riverbench.rng import stream
from sim import wls
from sim.constellation import CN0_OFFSET_DB, CODE_NOISE_SCALE, DEFAULT_EPHEMERIS, NMEA_SYSTEM, Constellation, System
from sim.doppler import DopplerConfig, DopplerVelocity
from sim.ephemeris import EphemerisError
from sim.geodesy import LocalFrame
from sim.gnss_fix import FixTruth, GnssFix, SatelliteReport, SatelliteTruth
from sim.gnss_profiles import DEFAULT_PROFILE, Corrections, ProfileName, with_profile
from sim.multipath import L1_WAVELENGTH_M, FacadeIndex, code_multipath_error
from sim.nmea.systems import PRIMARY
from sim.pseudorange import PseudorangeNoise, RangeErrors, SmoothingLock
from sim.receiver_filter import CvKalman, FilterConfig
from sim.rtk import RTK_FIXED, RTK_FLOAT, RtkConfig, RtkErrors, RtkLock
from sim.scene import split
from sim.traffic import Traffic
from sim.visibility import trace

DEFAULT_EPOCH = datetime(2018, 7, 29, 15, 0, 0, tzinfo=UTC)
"""Default scenario start: 11:00 local time in Boston on a July day, near the middle of the shipped ephemeris file's span
(four systems: 2018-07-29 11:45 to 19:15 UTC, Constellation.start_utc and end_utc), with hours to spare for any route."""
DEFAULT_CONSTELLATIONS: tuple[System, ...] = ("GPS", "GLONASS", "GALILEO", "BEIDOU")
"""A modern single-frequency receiver tracks all four global systems (u-blox M9/M10 and F9 default configuration,
CFG-SIGNAL: GPS, GLONASS, Galileo, BeiDou enabled)."""


VELOCITY_STEP_S = 1e-3
"""Step of the antenna's true velocity by differences: over 1 ms a mast swaying in waves (1-2 m/s^2) moves the
difference by 1-2 mm/s, far below the Doppler's centimetres a second."""


class OutageWindow(BaseModel):
    """A forced outage: no satellite is tracked for start_s <= t < end_s (scenario time, s)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    start_s: float = Field(description="start of the window, scenario time, s (inclusive)")
    end_s: float = Field(description="end of the window, scenario time, s (exclusive; after start_s)")

    @model_validator(mode="after")
    def _ordered(self) -> OutageWindow:
        if not self.end_s > self.start_s:
            raise ValueError(f"end_s ({self.end_s}) must be after start_s ({self.start_s})")
        return self


class BiasWindow(OutageWindow):
    """A forced fault for start_s <= t < end_s on top of the physics: a position offset and/or one satellite's range bias."""

    enu_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0),
        description="shifts the raw position solution by this ENU offset, m (applied through the pseudoranges, "
        "-u_i . offset on satellite i, so DOP and residuals stay consistent; default none)",
    )
    prn: int | None = Field(None, ge=1, description="GPS satellite (PRN) that range_m biases (a classic integrity-monitor test; default none)")
    range_m: float = Field(0.0, description="range bias added to satellite prn, m (default 0)")


class MultipathConfig(BaseModel):
    """Facade reflections (image method)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    search_radius_m: float = Field(
        200.0,
        gt=0.0,
        le=1000.0,
        description="Only facades within this distance of the antenna reflect, m (bounds the cost; 200 m reaches the buildings across a wide river).",
    )
    reflection_amplitude: float = Field(
        0.4,
        gt=0.0,
        lt=1.0,
        description="Amplitude of a facade reflection relative to the direct signal (0.4 = -8 dB: reflection and RHCP antenna losses).",
    )
    correlator_spacing_chips: float = Field(0.2, gt=0.0, le=1.0, description="Early-late correlator spacing of the code tracking loop, C/A chips.")


class GnssConfig(BaseModel):
    """All settings of the simulated receiver. The fields' own defaults are a consumer GPS module (profile 'consumer');
    `profile` picks a receiver class whose datasheet values fill the fields not written (sim.gnss_profiles)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    profile: ProfileName = Field(
        DEFAULT_PROFILE,
        description="Receiver class whose values are the defaults of the other fields (sim.gnss_profiles): 'sbas' a marine "
        "L1 receiver with SBAS corrections and carrier-smoothed code (Hemisphere V102 class: < 1.0 m 95% horizontal; "
        "NovAtel SMART2 SBAS: 0.6 m RMS, 0.9 m 95%), 'sbas_gps' the same tracking GPS alone (the V102, the field study's "
        "era), 'consumer' a u-blox NEO-M8N (2.5 m CEP, GPS), 'rtk' a u-blox ZED-F9P "
        "with a base station (0.01 m + 1 ppm CEP fixed, convergence < 10 s). A field written beside it wins.",
    )
    rate_hz: float = Field(5.0, ge=1.0, le=10.0, description="Output rate, Hz (1-10).")
    epoch_utc: datetime = Field(DEFAULT_EPOCH, description="UTC at scenario time 0 (satellite geometry); must fall inside the ephemeris file.")
    constellations: tuple[System, ...] = Field(
        DEFAULT_CONSTELLATIONS,
        min_length=1,
        description="Satellite systems tracked: any of GPS, GLONASS, GALILEO, BEIDOU (default all four, as a modern receiver).",
    )
    ephemeris: str = Field(
        DEFAULT_EPHEMERIS,
        min_length=1,
        description="RINEX 3 navigation file the satellite positions come from: a shipped file's name (sim/data; default "
        "the IGS station ELKO's broadcast ephemerides of 2018-07-29 11:00-19:59 GPST) or a path.",
    )
    elevation_mask_deg: float = Field(12.0, ge=0.0, lt=90.0, description="Satellites below this are not used, deg.")
    pdop_mask: float = Field(25.0, gt=1.0, description="Raw solutions with a larger PDOP are discarded (u-blox default 25).")
    antenna_offset_m: tuple[float, float, float] = Field((0.0, 0.0, 1.3), description="Antenna phase centre on base_link (x fwd, y left, z up), m.")
    noise: PseudorangeNoise = Field(default_factory=PseudorangeNoise, description="Pseudorange error model.")
    multipath: MultipathConfig = Field(default_factory=MultipathConfig, description="Facade reflections.")
    doppler: DopplerConfig = Field(default_factory=DopplerConfig, description="Range-rate errors of the reported velocity (sim.doppler).")
    foliage_loss_db_per_m: float = Field(
        1.3,
        ge=0.0,
        le=10.0,
        description="C/N0 lost per metre of tree crown a direct signal crosses, dB/m (crowns attenuate, they do not block). "
        "Goldhirsh & Vogel, Handbook of Propagation Effects for Vehicular and Personal Mobile Satellite Systems "
        "(NASA RP-1274, ch. 2), single roadside trees in full foliage at L-band: ~1-2 dB/m; ITU-R P.833 gives "
        "the same order for short vegetation paths (Weissberger: 0.45 f^0.284 dB/m, 0.51 at 1.575 GHz, dense woodland).",
    )
    filter_mode: Literal["kalman", "raw"] = Field(
        "kalman", description="'kalman': the receiver's CV filter output; 'raw': single-epoch WLS solutions."
    )
    filter: FilterConfig = Field(default_factory=FilterConfig, description="Receiver navigation filter.")
    coast_limit_s: float = Field(10.0, ge=0.0, description="Dead reckoning (quality 6) this long after the last raw fix, then quality 0, s.")
    corrections: Corrections = Field(
        default_factory=Corrections, description="Differential corrections applied (none, SBAS, RTK) and their GGA age and station."
    )
    rtk: RtkConfig = Field(default_factory=RtkConfig, description="RTK engine (used when corrections.kind is 'rtk'; sim.rtk).")
    forced_outages: tuple[OutageWindow, ...] = Field((), description="Forced outage intervals (off by default).")
    forced_biases: tuple[BiasWindow, ...] = Field((), description="Forced position/range biases (off by default).")

    @model_validator(mode="before")
    @classmethod
    def _profile_defaults(cls, data: object) -> object:
        return with_profile(data) if isinstance(data, dict) else data

    @field_validator("epoch_utc")
    @classmethod
    def _utc(cls, value: datetime) -> datetime:
        value = value if value.tzinfo is not None else value.replace(tzinfo=UTC)
        return value.astimezone(UTC)

    @field_validator("constellations")
    @classmethod
    def _distinct(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if len(set(value)) != len(value):
            raise ValueError(f"constellations lists a system twice: {list(value)}")
        return value

    @model_validator(mode="after")
    def _covered(self) -> GnssConfig:
        try:
            Constellation.load(self.ephemeris, self.constellations).check(self.epoch_utc)
        except EphemerisError as exc:
            raise ValueError(str(exc)) from None
        return self


class _Navigator:
    """One chain from raw WLS solutions to reported fixes: the WLS start point, the receiver's
    navigation filter, and its coast-then-invalid logic."""

    def __init__(self, config: GnssConfig):
        self.config = config
        self.filter = CvKalman(config.filter)
        self.start = np.zeros(4)
        self.last_raw_t = -np.inf
        self.last_raw_enu: np.ndarray | None = None

    def solve(self, sat_enu: np.ndarray, pseudorange: np.ndarray, sigma: np.ndarray) -> wls.Solution | None:
        """This epoch's raw solution from the tracked satellites, or None (fewer than 4, or PDOP over the mask)."""
        if len(pseudorange) < 4:
            return None
        solution = wls.solve(sat_enu, pseudorange, sigma, self.start)
        self.start = np.append(solution.enu, solution.clock_m)
        return solution if solution.pdop <= self.config.pdop_mask else None

    def step(self, t: float, solution: wls.Solution | None) -> tuple[np.ndarray, np.ndarray, int]:
        """Reported ENU position, velocity and GGA quality from this epoch's raw solution (or none)."""
        nothing = np.full(3, np.nan)
        rate_hz = self.config.rate_hz
        if self.config.filter_mode == "raw":
            if solution is None:
                return nothing, nothing, 0
            velocity = nothing
            if self.last_raw_enu is not None and t - self.last_raw_t <= 1.5 / rate_hz:
                velocity = (solution.enu - self.last_raw_enu) / (t - self.last_raw_t)
            self.last_raw_t, self.last_raw_enu = t, solution.enu
            return solution.enu.copy(), velocity, 1
        kf = self.filter
        kf.predict(t)
        if solution is not None:
            kf.update(solution.enu, solution.cov)
            self.last_raw_t = t
            return kf.position, kf.velocity, 1
        if kf.initialised and t - self.last_raw_t <= self.config.coast_limit_s:
            return kf.position, kf.velocity, 6
        kf.reset()
        return nothing, nothing, 0


@dataclass
class _WorldGeometry:
    """What the receiver derives once per world: the facade index and the local ENU frame."""

    world: object
    facades: FacadeIndex
    frame: LocalFrame


class GnssReceiver:
    """Simulated GNSS receiver; call `.fix(world, trajectory, t)` at increasing times t (s)."""

    def __init__(self, rate_hz: float = 5.0, seed: int = 0, **more):
        self.config = GnssConfig(rate_hz=rate_hz, **more)
        self.seed = int(seed)
        self.constellation = Constellation.load(self.config.ephemeris, self.config.constellations)
        self._cn0_offset = self.constellation.per_satellite(CN0_OFFSET_DB)
        self._code_scale = self.constellation.per_satellite(CODE_NOISE_SCALE)
        self._nmea_system = [NMEA_SYSTEM[s] for s in self.constellation.system]
        self._errors = RangeErrors(self.config.noise, len(self.constellation), stream(self.seed, "gnss.range_errors"))
        self._cn0_rng = stream(self.seed, "gnss.cn0")
        self._doppler = DopplerVelocity(self.config.doppler, len(self.constellation), stream(self.seed, "gnss.doppler"))
        self._navigator = _Navigator(self.config)
        self._open_sky = _Navigator(self.config)
        self._smoothing = SmoothingLock(self.config.noise, len(self.constellation), stream(self.seed, "gnss.smoothing"))
        self._open_sky_smoothing = SmoothingLock(self.config.noise, len(self.constellation), stream(self.seed, "gnss.smoothing_open_sky"))
        rtk = self.config.corrections.kind == "rtk"
        self._rtk_errors = RtkErrors(self.config.rtk, stream(self.seed, "gnss.rtk")) if rtk else None
        self._rtk_lock = RtkLock.start(self.config.rtk)
        self._open_sky_rtk_lock = RtkLock.start(self.config.rtk)
        self._offset = np.array(self.config.antenna_offset_m, dtype=float)
        self._mask = np.deg2rad(self.config.elevation_mask_deg)
        self._worlds: dict[int, _WorldGeometry] = {}
        self._last_t: float | None = None

    @property
    def rate_hz(self) -> float:
        return self.config.rate_hz

    def check_covers(self, t_start: float, t_end: float) -> None:
        """ValueError naming the ephemeris file's span when scenario times t_start..t_end (s) are not all inside it."""
        for t, what in ((t_start, "gnss: the run's start"), (t_end, "gnss: the run's end")):
            self.constellation.check(self.config.epoch_utc + timedelta(seconds=float(t)), what)

    def epochs(self, t_end: float, t_start: float = 0.0) -> np.ndarray:
        """Output times from t_start (inclusive) to t_end (exclusive) at rate_hz."""
        return t_start + np.arange(int(np.ceil((t_end - t_start) * self.rate_hz - 1e-9))) / self.rate_hz

    def _geometry(self, world) -> _WorldGeometry:
        cached = self._worlds.get(id(world))
        if cached is None or cached.world is not world:
            facades = FacadeIndex.from_world(world, self.config.multipath.search_radius_m)
            cached = _WorldGeometry(world, facades, LocalFrame.at(*world.origin))
            self._worlds[id(world)] = cached
        return cached

    def _antenna(self, trajectory, t: float) -> np.ndarray:
        pose = np.asarray(trajectory.pose(t), dtype=float)
        if pose.shape != (4, 4):
            raise ValueError(f"gnss: trajectory.pose({t}) must be a 4x4 matrix, got shape {pose.shape}")
        if not np.isfinite(pose).all():
            raise ValueError(f"gnss: trajectory pose at t={t} s is not finite (NaN or inf)")
        return pose[:3, :3] @ self._offset + pose[:3, 3]

    def _antenna_velocity(self, trajectory, t: float, antenna: np.ndarray) -> np.ndarray:
        """The antenna's true velocity at t (ENU, m/s): its position VELOCITY_STEP_S before t (after t at the
        trajectory's start) differenced with `antenna`, its position at t."""
        try:
            return (antenna - self._antenna(trajectory, t - VELOCITY_STEP_S)) / VELOCITY_STEP_S
        except ValueError:  # t is the trajectory's first time
            return (self._antenna(trajectory, t + VELOCITY_STEP_S) - antenna) / VELOCITY_STEP_S

    def fix(self, world, trajectory, t: float) -> GnssFix:
        """The receiver's output at scenario time t (s); times must increase from call to call. `world` is a World
        or a sim.Scene, whose movers at time t block signals and, when steel, reflect them."""
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"gnss: fix time must be finite, got {t}")
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f"gnss: fix times must increase, got t={t} after t={self._last_t}")
        utc = self.config.epoch_utc + timedelta(seconds=t)
        antenna = self._antenna(trajectory, t)
        world, traffic = split(world)
        geo = self._geometry(world)
        self._last_t = t

        sat_enu, geometric, dirs, el, view = self._sky(geo, antenna, utc)
        los, nlos, extra = self._paths(world, traffic, geo, antenna, dirs, t)

        # Signal strength and tracking.
        mp = self.config.multipath
        noise = self.config.noise
        cn0_open_sky = noise.cn0(el) + self._cn0_offset[view] + noise.cn0_jitter_db * self._cn0_rng.standard_normal(len(view))
        cn0 = cn0_open_sky + np.where(nlos, 20.0 * np.log10(mp.reflection_amplitude), 0.0)
        cn0[los] -= self.config.foliage_loss_db_per_m * world.crowns.path_length(antenna, dirs[los])
        tracked = (los | nlos) & (cn0 >= noise.tracking_threshold_dbhz)
        if any(w.start_s <= t < w.end_s for w in self.config.forced_outages):
            tracked[:] = False

        # Pseudoranges.
        bias = np.zeros(len(view))
        bias[nlos] = extra[nlos]
        los_mp = los & np.isfinite(extra)
        if los_mp.any():
            bias[los_mp] = code_multipath_error(
                extra[los_mp],
                mp.reflection_amplitude,
                mp.correlator_spacing_chips,
                2.0 * np.pi * extra[los_mp] / L1_WAVELENGTH_M,
            )
        bias += self._forced_bias(t, view, dirs)
        slow, white = self._errors.advance(t)
        mapping = 1.0 / np.sin(el)
        clear = cn0_open_sky >= noise.tracking_threshold_dbhz
        open_sky_range = geometric + self._errors.clock_m(t) + mapping * (slow[view] + self._code_scale[view] * white[view])
        pseudorange = open_sky_range + bias
        sigma = open_sky_sigma = noise.sigma(el)
        if noise.restart_white_zenith_m is not None:  # carrier smoothing restarted where lock was lost (SmoothingLock)
            unsmoothed, scale = self._smoothing.update(view, tracked)
            open_unsmoothed, open_scale = self._open_sky_smoothing.update(view, clear)
            code = self._code_scale[view]
            pseudorange = geometric + self._errors.clock_m(t) + mapping * (slow[view] + code * (white[view] + unsmoothed)) + bias
            open_sky_range = geometric + self._errors.clock_m(t) + mapping * (slow[view] + code * (white[view] + open_unsmoothed))
            sigma, open_sky_sigma = noise.sigma(el, scale), noise.sigma(el, open_scale)

        solution = self._navigator.solve(sat_enu[tracked], pseudorange[tracked], sigma[tracked])
        enu, velocity, quality = self._navigator.step(t, solution)
        doppler = self._doppler.error(t, view, tracked, dirs, el, nlos, extra, 1.0 / self.config.rate_hz)
        if solution is not None and doppler is not None:  # a measured fix reports the Doppler velocity, a coast its filter's
            velocity = self._antenna_velocity(trajectory, t, antenna) + doppler
        open_sky_enu, _, open_sky_quality = self._open_sky.step(t, self._open_sky.solve(sat_enu[clear], open_sky_range[clear], open_sky_sigma[clear]))

        prn = self.constellation.prn[view].tolist()
        rtk_errors = self._rtk_errors.advance(t) if self._rtk_errors is not None else None
        enu, quality, age = self._differential(
            t,
            antenna,
            enu,
            quality,
            self._rtk_lock.update(t, view[tracked & los].tolist(), bool((tracked & nlos).any())),
            rtk_errors,
        )
        open_sky_enu = self._differential(
            t,
            antenna,
            open_sky_enu,
            open_sky_quality,
            self._open_sky_rtk_lock.update(t, view[clear].tolist(), False),
            rtk_errors,
        )[0]
        az = (np.rad2deg(np.arctan2(dirs[:, 0], dirs[:, 1])) % 360.0).tolist()
        used = tracked if solution is not None else np.zeros(len(view), dtype=bool)
        snr = np.where(tracked, cn0, 0.0).tolist()
        system = [self._nmea_system[k] for k in view]
        signal = [PRIMARY[s] for s in system]
        sats = tuple(map(SatelliteReport, prn, az, np.rad2deg(el).tolist(), snr, used.tolist(), system, signal))
        sat_truth = tuple(map(SatelliteTruth, prn, los.tolist(), nlos.tolist(), bias.tolist(), system))
        lat, lon, alt = geo.frame.geodetic_of_enu(enu) if quality else (np.nan, np.nan, np.nan)
        speed = float(np.hypot(velocity[0], velocity[1]))
        course = float(np.rad2deg(np.arctan2(velocity[0], velocity[1])) % 360.0) if np.isfinite(speed) else np.nan
        return GnssFix(
            stamp=t,
            lat=lat,
            lon=lon,
            alt=alt,
            enu=enu,
            quality=quality,
            num_sats=int(used.sum()),
            hdop=solution.hdop if solution else np.nan,
            vdop=solution.vdop if solution else np.nan,
            pdop=solution.pdop if solution else np.nan,
            sats=sats,
            utc=utc.isoformat(timespec="microseconds"),
            truth=FixTruth(enu=antenna, error=enu - antenna, sats=sat_truth, open_sky_error=open_sky_enu - antenna),
            speed_mps=speed,
            course_deg=course,
            correction_age_s=age,
            station_id=self.config.corrections.station_id if np.isfinite(age) else None,
            systems=tuple(NMEA_SYSTEM[s] for s in self.config.constellations),
        )

    def _differential(
        self, t: float, antenna: np.ndarray, enu: np.ndarray, quality: int, rtk: tuple[int, float], rtk_errors: tuple[np.ndarray, np.ndarray] | None
    ) -> tuple[np.ndarray, int, float]:
        """The fix after the corrections: position, GGA quality and correction age (s; NaN when not differential).
        Only a measured code fix (quality 1) is corrected; dead reckoning and no fix stay as they are."""
        kind = self.config.corrections.kind
        if quality != 1 or kind == "none":
            return enu, quality, np.nan
        age = self.config.corrections.age_s(t)
        if rtk_errors is None:  # SBAS: the corrections are in the range error model, the fix is differential
            return enu, 2, age
        rtk_quality, converging_s = rtk
        fixed_error, float_error = rtk_errors
        if rtk_quality == RTK_FIXED:
            return antenna + fixed_error, RTK_FIXED, age
        weight = self._rtk_lock.float_weight(converging_s)
        return antenna + float_error + weight * (enu - antenna), RTK_FLOAT, age

    def _sky(self, geo: _WorldGeometry, antenna: np.ndarray, utc: datetime):
        """Satellites above the mask (with a current ephemeris): ENU positions, ranges, unit directions, elevations, indices."""
        ecef = self.constellation.ecef(utc)
        known = np.nonzero(np.isfinite(ecef[:, 0]))[0]
        sat_enu = np.full_like(ecef, np.nan)
        sat_enu[known] = geo.frame.enu_of_ecef(ecef[known])
        diff = sat_enu - antenna
        geometric = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        up = diff[:, 2] / geometric
        view = known[up[known] >= np.sin(self._mask)]
        return sat_enu[view], geometric[view], diff[view] / geometric[view, None], np.arcsin(up[view]), view

    def _paths(self, world, traffic: Traffic, geo: _WorldGeometry, antenna: np.ndarray, dirs: np.ndarray, t: float):
        """Per satellite: direct path clear (los), received only by reflection (nlos), and the
        extra path (m) of its shortest clear facade reflection (inf if none). Tree crowns block nothing:
        a direct path through them is attenuated (see `foliage_loss_db_per_m`); reflected ones are not."""
        reflections = geo.facades.reflections(antenna, dirs)
        movers = None
        if traffic:
            reflections = reflections.joined(traffic.reflections(antenna, dirs, t, self.config.multipath.search_radius_m))
            movers = functools.partial(traffic.distance, t=t)
        paths = trace(world.gnss_scene, antenna, dirs, reflections, movers)
        if paths.inside_solid:
            raise ValueError(
                f"gnss: antenna at ENU ({antenna[0]:.2f}, {antenna[1]:.2f}, {antenna[2]:.2f}) at t={t} s "
                f"is inside a solid part of world {getattr(world, 'name', '?')!r}"
            )
        extra = np.full(len(dirs), np.inf)
        if len(reflections):
            ok = np.nonzero(paths.reflection_clear)[0]
            ok = ok[np.argsort(-reflections.extra_m[ok])]  # assign longest first: the shortest wins
            extra[reflections.sat[ok]] = reflections.extra_m[ok]
        return paths.los, ~paths.los & np.isfinite(extra), extra

    def _forced_bias(self, t: float, view: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Range biases (m) of the satellites in view from the forced-bias windows active at t."""
        bias = np.zeros(len(view))
        for window in self.config.forced_biases:
            if window.start_s <= t < window.end_s:
                bias -= dirs @ np.asarray(window.enu_m)
                if window.prn is not None:
                    gps = np.array([self.constellation.system[k] == "GPS" for k in view], dtype=bool)
                    bias[gps & (self.constellation.prn[view] == window.prn)] += window.range_m
        return bias
