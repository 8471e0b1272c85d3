"""Estimator parameters: what every estimator is given (odometry source, monitor, vessel geometry) and what the built-ins share."""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

SENSORS = ("gnss", "odometry", "imu", "compass")
"""What an estimator can be fed: receiver fixes, scan-matching odometry, IMU samples, compass headings."""
DEFAULT_SENSORS = ("gnss", "odometry")
DEFAULT_MOUNT = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 1.8), (0.0, 0.0, 0.0, 1.0))


class BaseEstimatorParams(BaseModel):
    """What every estimator is given, a plugin's `Params` included: odometry source, monitor, vessel geometry."""

    model_config = ConfigDict(extra="forbid")
    matcher: str = Field(
        "gicp",
        min_length=1,
        description="name of the matcher whose odometry this estimator uses [gicp: it reports a covariance with its "
        "degenerate directions, which kiss_icp does not]",
    )
    monitor: str = Field("consistency", description="GPS integrity monitor (default set per estimator) [consistency]")
    monitor_params: dict = Field(default_factory=dict, description="the monitor's parameters [{}: its own defaults]")
    mount: tuple[tuple[float, float, float, float], ...] = Field(
        DEFAULT_MOUNT, description="4x4 base_link<-lidar [identity rotation, lidar 1.8 m above base_link]"
    )
    antenna: tuple[float, float, float] = Field((0.0, 0.0, 1.3), description="antenna position on base_link, metres [(0, 0, 1.3)]")
    sensors: tuple[str, ...] = Field(
        DEFAULT_SENSORS,
        description="what the estimator is fed: any of gnss, odometry, imu, compass [gnss, odometry: GPS and scan matching]",
    )

    @field_validator("sensors")
    @classmethod
    def _known_sensors(cls, sensors: tuple[str, ...]) -> tuple[str, ...]:
        unknown = [s for s in sensors if s not in SENSORS]
        if unknown:
            raise ValueError(f"unknown sensor {unknown[0]!r} (known: {', '.join(SENSORS)})")
        if len(set(sensors)) != len(sensors):
            raise ValueError("a sensor is listed twice")
        return tuple(sensors)

    @field_validator("mount")
    @classmethod
    def _rigid(cls, mount: tuple) -> tuple:
        m = np.asarray(mount, dtype=float)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise ValueError("must be a finite 4x4 matrix")
        if not np.allclose(m[3], (0, 0, 0, 1)) or not np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-6):
            raise ValueError("must be a rigid transform (rotation and translation)")
        return mount


class EstimatorParams(BaseEstimatorParams):
    """Parameters the built-in estimators share beyond BaseEstimatorParams': GPS error model, start-up alignment, odometry noise, re-lock."""

    uere_m: float = Field(
        3.0,
        gt=0,
        description="range error scale; a fix's per-axis sigma is uere_m * HDOP / sqrt(2) [3.0, i.e. about 2.5 m CEP50 "
        "at HDOP 1, a consumer receiver]",
    )
    gps_correlation_s: float = Field(
        30.0,
        ge=0,
        description="time constant of the receiver's position error: its own filter and slowly changing multipath make "
        "consecutive fixes' errors alike, so the filters carry it as a first-order Gauss-Markov bias, and displacement "
        "tests expect a difference variance that grows as 1 - exp(-dt / gps_correlation_s) [30 s, as the simulated "
        "consumer receiver's error decorrelates (0.9 at 10 s, 0.7 at 30 s in open water); 0 treats fixes as independent]",
    )
    accept_dead_reckoning: bool = Field(False, description="use the receiver's own dead-reckoned output (GGA 6) as a fix [False]")
    initial_pose: tuple[float, float, float] | None = Field(
        None,
        description="(x, y, yaw_deg) of base_link at the first input if known, with initial_sigma [None]; otherwise the "
        "pose is found at start-up by aligning the odometry track with GPS over init_baseline_m",
    )
    initial_sigma: tuple[float, float] = Field((1.0, 5.0), description="(metres, degrees) standard deviation of a given initial_pose [(1.0, 5.0)]")
    init_baseline_m: float = Field(
        10.0,
        gt=0,
        description="start-up alignment needs at least this much GPS travel [10 m]; a re-lock re-aligns the same way when it can",
    )
    init_min_fixes: int = Field(
        5, ge=2, description="start-up alignment needs at least this many fixes [5]; a re-lock re-aligns the same way when it can"
    )
    init_max_hdop: float = Field(
        2.5,
        gt=0,
        description="start-up alignment uses only fixes with at most this HDOP [2.5]; a re-lock re-aligns the same way when it can",
    )
    init_max_yaw_sd_deg: float = Field(
        5.0,
        gt=0,
        description="start-up alignment needs a heading whose standard deviation (from the fit's residuals) is at most "
        "this [5 deg]; a re-lock re-aligns the same way when it can",
    )
    init_static_speed_mps: float = Field(
        0.3,
        gt=0,
        description="a vessel whose receiver reports a speed over ground below this on init_min_fixes consecutive kept "
        "fixes is at rest (moored): the estimator starts on its position, its heading unknown until motion, a compass or "
        "the receiver's course gives it [0.3 m/s: consumer receivers' Doppler speed is good to 0.05 m/s (u-blox NEO-M8 "
        "datasheet, velocity accuracy 50%), so a moored boat reports well under it and one under way never]",
    )
    init_static_s: float = Field(
        20.0,
        gt=0,
        description="a receiver that reports no speed (GGA only) shows a vessel at rest when its kept fixes over this long "
        "all stay within init_baseline_m / 2 of their mean [20 s: a boat at 0.5 m/s or more leaves that circle]",
    )
    init_velocity_sigma_mps: float = Field(
        0.5,
        gt=0,
        description="per-axis error of the receiver's velocity over ground (RMC/VTG speed and course) as the filters take it "
        "at start-up and re-lock, fused with the odometry's last step, which it outweighs only where the matcher left a "
        "direction unobserved [0.5 m/s: u-blox NEO-M8's datasheet gives 0.05 m/s (50%) in open sky; the simulated "
        "receiver's filtered velocity is off by 0.06-0.14 m/s median, 0.11-1.6 m/s p95 and up to 1.3 m/s in its first "
        "seconds (rough_water, charles_river, quickstart, canal_multipath, seed 0), so 0.5 covers it but a quay's NLOS]",
    )
    init_course_speed_mps: float = Field(
        1.0,
        gt=0,
        description="a vessel that started at rest takes its heading from the receiver's course over ground (RMC/VTG) once "
        "it reports at least this speed, and one under way starts on it (init_on_course) once init_min_fixes "
        "consecutive kept fixes report it [1 m/s: the course's own error, about speed error / speed, is then 3 deg]",
    )
    init_on_course: bool = Field(
        True,
        description="a vessel under way starts on its receiver's course over ground (RMC/VTG: Doppler, sim.doppler) once "
        "init_min_fixes consecutive kept fixes report at least init_course_speed_mps, its heading as uncertain as "
        "course_heading_sigma_deg, and refines the heading as it goes (the ekf from the receiver's velocity and the "
        "odometry, the pf from the fixes and the odometry) [True: started in 1 s at 5 Hz; False: waits for "
        "init_baseline_m of track to align the odometry with (Bootstrap.alignment): 6-13 s on the library's stretches, "
        "with no estimate meanwhile]",
    )
    course_heading_sigma_deg: float = Field(
        10.0,
        gt=0,
        description="standard deviation of a heading taken from the course over ground: wind and current set a small "
        "craft off its heading by its leeway and drift, typically 5-15 deg (Allen and Plourde 1999, Review of Leeway, "
        "USCG R&D Center CG-D-08-99) [10 deg]",
    )
    default_odom_sigma_m: float = Field(
        0.2,
        gt=0,
        description="per-scan translation noise assumed when a match has no covariance [0.2 m: kiss_icp, which has none, "
        "can lose the whole along-track motion of a scan on open water]",
    )
    default_odom_sigma_yaw_deg: float = Field(0.5, gt=0, description="per-scan yaw noise assumed when a match has no covariance [0.5 deg]")
    odom_floor_sigma_m: float = Field(
        0.03,
        ge=0,
        description="per-scan translation noise added to every reported match covariance, since Hessian covariances are optimistic [0.03 m]",
    )
    odom_floor_sigma_yaw_deg: float = Field(
        0.2,
        ge=0,
        description="per-scan yaw noise added to every reported match covariance, since Hessian covariances are optimistic [0.2 deg]",
    )
    odom_unobserved_sigma_m: float = Field(
        0.5,
        gt=0,
        description="a match direction whose reported per-scan sigma exceeds this carries no information (a degenerate "
        "ICP leaves its prior there, not a measurement): its variance is raised to 1e6 m^2, so that the filter takes that "
        "direction from its motion model and GPS [0.5 m, more than the boat moves in a scan]",
    )
    odom_slip_frac: float = Field(
        0.1,
        ge=0,
        description="a match that did not slip (see odom_slip_sigmas) has its variance along the direction of motion "
        "raised by (odom_slip_frac * the expected motion)^2 [0.1: gicp's along-track error is now about 1% of the motion "
        "outside degenerate stretches (benchmarks/outages.py); at 1.0 the filter's speed came from GPS alone and lagged "
        "the boat's speed changes into every blackout; 0 turns it off]",
    )
    odom_slip_sigmas: float = Field(
        3.0,
        ge=0,
        description="scan matchers on sparse river scans can slip along the direction of motion (a flat wall, a deck "
        "overhead or open water leaves it weakly constrained) with an optimistic covariance. A match that falls short of "
        "the motion the filter expects along that direction by more than this many of its own sigma slipped: that "
        "direction is made unobserved (gicp did this under charles_river's Charlestown Bridge before its planarity "
        "weighting: no motion at all, +-1 cm, for 15 s) [3.0; 0 turns it off]",
    )
    integrity_risk: float = Field(
        1e-5,
        gt=0,
        lt=1,
        allow_inf_nan=False,
        description="probability per epoch that the horizontal error exceeds the reported protection level "
        "(fusion.integrity) [1e-5: IMO Resolution A.1046(27)'s integrity risk for ocean, coastal and inland navigation "
        "(1e-5 per 3 hours), taken per epoch, which is stricter]",
    )
    relock_s: float = Field(
        30.0,
        gt=0,
        description="after this long with every measured fix refused although fixes keep coming, the filter re-locks "
        "onto GPS (position reset to the latest fix, monitor restarted), recorded as an event; fixes refused on their "
        "own evidence (an NLOS C/N0, a high HDOP) neither count nor become the re-lock point [30 s]",
    )


class InertialParams(BaseModel):
    """How the ekf and the pf use an IMU (gyro-driven yaw with a yaw-rate bias state, tilt from the accelerometer) and a
    magnetic compass (heading updates behind an innovation gate and a check of the field against the local one)."""

    model_config = ConfigDict(extra="forbid")

    gyro_noise_dps: float | None = Field(
        None, gt=0, description="gyro white noise density, deg/s/sqrt(Hz) [None: the density the IMU samples state, the datasheet's]"
    )
    latitude_deg: float = Field(
        42.3539,
        ge=-90,
        le=90,
        description="latitude the boat runs at, deg: the Earth's rate about the vertical there (15.04 sin(lat) deg/h) is taken off "
        "the gyro's yaw rate, as an AHRS does [42.3539: the worlds' origin on the Charles River]",
    )
    gyro_bias_sigma_dps: float = Field(
        1.0, gt=0, description="initial 1-sigma of the yaw-rate bias, deg/s [1.0: a consumer MEMS gyro's zero-rate offset, BMI088 +-1 deg/s]"
    )
    gyro_bias_walk_dph: float = Field(
        60.0,
        ge=0,
        description="random walk of the yaw-rate bias in the filter, deg/h/sqrt(h) [60: follows an in-run bias of a few deg/h "
        "wandering on a minute scale, the MTi-630's, and the Earth's 10 deg/h about the vertical, which the bias also takes up]",
    )
    odom_floor_sigma_yaw_deg: float = Field(
        0.02,
        ge=0,
        description="with an IMU, the per-scan yaw noise added to every match covariance instead of the estimator's "
        "odom_floor_sigma_yaw_deg, deg [0.02: the match's yaw now mostly tells the gyro's bias; at the 0.2 deg floor "
        "(0.63 deg/sqrt(s)) a bias under ~30 deg/h stays hidden for a quarter of an hour and canal_lock's ekf with the "
        "MTi-630 drifted 7 deg through its GPS-less second half (benchmarks/inertial.py)]",
    )
    particle_yaw_walk_dps: float = Field(
        0.3,
        ge=0,
        description="pf: extra random walk of each particle's yaw on top of the gyro's noise, deg/s/sqrt(Hz) [0.3: with the gyro "
        "alone the particles' yaws hardly spread and GPS and odometry could no longer select a better one]",
    )
    compass_sigma_deg: float | None = Field(None, gt=0, description="compass heading 1-sigma, deg [None: what each sample states]")
    compass_interval_s: float = Field(
        1.0,
        ge=0,
        description="use at most one compass heading per this interval, s [1.0: a compass's error (residual hard iron, tilt) is "
        "correlated over seconds; taking every 10 Hz sample as independent would make the filter overconfident]",
    )
    compass_gate_prob: float = Field(
        0.999, gt=0.5, lt=1.0, description="chi-square (1 dof) gate on a heading's innovation [0.999: refused beyond 3.3 sigma]"
    )
    compass_gyro_check: bool = Field(
        True,
        description="with an IMU, refuse a compass heading whose change disagrees with the gyro's integrated yaw beyond what "
        "either can err by (fusion.compass_check): catches the gentle 1-3 deg a steel structure bends the heading by, "
        "which the innovation gate lets through [True]",
    )
    compass_iron_share: float = Field(
        0.03,
        ge=0,
        description="share of the heading turned through that the residual iron error may change the compass heading by, "
        "1 sigma [0.03: a 0.28 uT residual hard iron is 1.4 % of the 20.6 uT horizontal field, its error changing by at "
        "most that per radian turned; 0.5 % soft iron adds about as much at twice the heading's frequency]",
    )
    compass_check_fit_s: float = Field(
        60.0,
        gt=0,
        description="span of trusted headings the check fits its line compass - gyro to, s [60: 600 headings at 10 Hz fix "
        "the line to a few hundredths of a degree while the MTi-630's bias wanders by about its 8 deg/h in-run stability "
        "over its 45 s correlation time, which moves the integral by a tenth of a degree]",
    )
    compass_check_average_s: float = Field(
        3.0,
        gt=0,
        description="a heading's offset is averaged over this long before it is compared, s [3.0: 30 outputs at 10 Hz take "
        "an MTi's 0.5 deg white scatter (0.2 deg roll/pitch error x tan of Boston's 66 deg dip) to 0.09 deg, at 1.5 s of delay]",
    )
    compass_check_min_headings: int = Field(
        100, ge=3, description="the fewest trusted headings the check fits a line to; before, every heading passes [100: 10 s at 10 Hz]"
    )
    field_ut: float = Field(
        51.32, gt=0, description="the undisturbed field intensity the boat's configuration knows, microtesla [IGRF-14 at Boston, 2025.0]"
    )
    dip_deg: float = Field(66.35, ge=-90, le=90, description="the undisturbed inclination, deg [IGRF-14 at Boston, 2025.0]")
    field_tolerance: float = Field(
        0.02,
        gt=0,
        description="a heading whose field intensity differs from field_ut by more than this share is refused as disturbed "
        "[0.02: 1 uT, about three times the residual hard iron and noise]",
    )
    dip_tolerance_deg: float = Field(
        1.0, gt=0, description="a heading whose dip differs from dip_deg by more than this is refused as disturbed [1.0]"
    )


class MotionModelParams(EstimatorParams):
    """Vessel motion and GPS error model shared by the ekf and the pf."""

    accel_sigma: float = Field(
        0.2,
        gt=0,
        description="white-noise acceleration density of the forward body velocity, m/s^2/sqrt(Hz) [0.2: loose enough "
        "that the speed follows the scan matcher's through the boat's speed changes (the simulated trajectory "
        "accelerates at up to 0.03 m/s^2), which is what the filter coasts on where a deck or a lock leaves the motion "
        "along the route unobserved (at 0.1 it lagged by 0.1-0.2 m/s into charles_river's blackouts); stiff enough that "
        "GPS noise does not pull it below the speed at which the slip test still sees a matcher reporting a confident "
        "stop (at 0.3 one seed in six lost the boat so)]",
    )
    lateral_accel_sigma: float = Field(
        0.05,
        gt=0,
        description="white-noise acceleration density of the sideways body velocity, m/s^2/sqrt(Hz) [0.05: a boat hardly crabs]",
    )
    yaw_accel_sigma_deg: float = Field(3.0, gt=0, description="white-noise acceleration density of the yaw rate, deg/s^2/sqrt(Hz) [3.0]")
    gps_white_sigma_m: float = Field(0.3, gt=0, description="per-axis white part of the GPS error on top of the correlated bias, m [0.3]")
    inertial: InertialParams | None = Field(
        None, description="how IMU samples and compass headings are used when the estimator's sensors include imu or compass [their defaults]"
    )

    def bias_variance(self, axis_var: float) -> float:
        """Per-axis variance of the receiver's correlated error, given its total per-axis variance
        (the white part taken off, floored at it)."""
        white = self.gps_white_sigma_m**2
        return max(axis_var - white, white)
