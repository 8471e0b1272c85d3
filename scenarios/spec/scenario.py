"""Scenario files: TOML validated by pydantic models that wrap the packages' own parameter models.

One source of truth: `[vessel]` is `sim.trajectory.TrajectoryConfig`, `[lidar]` is
`sim.lidar.HDL32EConfig`, `[gnss]` is `sim.gnss.GnssConfig`, `[world_params]` the preset's model,
each matcher's and estimator's `params` their own models. A resolved scenario has every default
filled in; its hash (of everything but name and description) is its identity in sweeps.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

import fusion
import matcher
import worlds
from fusion.monitors import Cn0Templates
from fusion.params import DEFAULT_SENSORS
from riverbench.errors import validation_message
from riverbench.plugins import is_path as is_plugin_path
from scenarios.score.expectations import Expectation
from scenarios.spec.command import KIND as COMMAND
from scenarios.spec.command import CommandSpec
from sim.autopilot import AutopilotConfig
from sim.dynamics import WamvDynamics
from sim.gnss import GnssConfig
from sim.imu import ImuConfig, samples_per_period
from sim.lidar import HDL32EConfig
from sim.magnetic_compass import CompassConfig
from sim.traffic import TrafficConfig
from sim.trajectory import TrajectoryConfig, mount_matrix

ID_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*$"
SEEDED_SECTIONS = ("vessel", "lidar")
"""Sections whose package model has its own seed: in a scenario every component takes the scenario's."""


class Stretch(BaseModel):
    """The part of the route to run: by time (start_s, end_s) or by route station (start_m, end_m).

    Times are seconds on the vessel's whole trajectory; stations are metres along the route,
    converted to times on that trajectory, so a stretch is exactly a piece of the whole run.
    Defaults: the whole trajectory.
    """

    model_config = ConfigDict(extra="forbid")

    start_s: float | None = Field(None, ge=0, description="first scan time, s (default: 0)")
    end_s: float | None = Field(None, gt=0, description="end time, s (default: the trajectory's end)")
    start_m: float | None = Field(None, ge=0, description="route station where the stretch starts, m")
    end_m: float | None = Field(None, gt=0, description="route station where the stretch ends, m")

    @model_validator(mode="after")
    def _one_kind(self) -> Stretch:
        by_time = self.start_s is not None or self.end_s is not None
        by_station = self.start_m is not None or self.end_m is not None
        if by_time and by_station:
            raise ValueError(
                "give the stretch by time (start_s, end_s) or by station (start_m, end_m), not both "
                "(--set replaces it whole with stretch={start_s = 10.0, end_s = 60.0})"
            )
        for a, b in ((self.start_s, self.end_s), (self.start_m, self.end_m)):
            if a is not None and b is not None and not b > a:
                raise ValueError(f"the stretch must end after it starts (got {a} .. {b})")
        return self

    def times(self, trajectory) -> tuple[float, float]:
        """(t_start, t_end) in seconds on `trajectory` (a sim.Trajectory)."""
        if self.start_m is None and self.end_m is None:
            t0 = 0.0 if self.start_s is None else self.start_s
            t1 = trajectory.duration if self.end_s is None else self.end_s
        else:
            t0 = 0.0 if self.start_m is None else _time_at_station(trajectory, self.start_m)
            t1 = trajectory.duration if self.end_m is None else _time_at_station(trajectory, self.end_m)
        if not 0.0 <= t0 < t1 <= trajectory.duration + 1e-6:
            raise ValueError(f"stretch: {t0:.1f}..{t1:.1f} s is not inside the trajectory's 0..{trajectory.duration:.1f} s")
        return float(t0), float(min(t1, trajectory.duration))


def _time_at_station(trajectory, station_m: float) -> float:
    """The time the vessel reaches route station `station_m` (station(t) increases monotonically)."""
    from scipy.optimize import brentq

    lo, hi = float(trajectory.station(0.0)), float(trajectory.station(trajectory.duration))
    if not lo - 1e-6 <= station_m <= hi + 1e-6:
        raise ValueError(f"stretch: station {station_m} m is outside the trajectory's {lo:.1f}..{hi:.1f} m")
    if station_m <= lo:
        return 0.0
    if station_m >= hi:
        return trajectory.duration
    return float(brentq(lambda t: float(trajectory.station(t)) - station_m, 0.0, trajectory.duration, xtol=1e-6))


class MatcherSpec(BaseModel):
    """A scan matcher under test: `kind` one of matcher.available() or `plugin` a 'package.module:Class';
    `params` its own model's fields."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(..., pattern=ID_PATTERN, description="name of this instance in metrics and files (e.g. 'gicp_fine')")
    kind: str | None = Field(None, description="matcher kind: pcl6d, bev3dof, kiss_icp, gicp or a name an installed plugin registers")
    plugin: str | None = Field(None, description="instead of kind: a plugin class 'package.module:Class' (installed or on PYTHONPATH)")
    params: dict = Field(default_factory=dict, description="the kind's parameters (see `riverbench scenarios show`)")

    @property
    def ref(self) -> str:
        """What matcher.create takes: the kind or the plugin path."""
        return self.kind or self.plugin or ""

    @model_validator(mode="after")
    def _resolve(self) -> MatcherSpec:
        _check_ref("matcher", self.id, self.kind, self.plugin)
        model = matcher.params_model(self.ref)
        self.params = _validated(model, self.params, f"matcher {self.id!r} ({self.ref})")
        return self


class EstimatorSpec(BaseModel):
    """A fusion estimator under test (`kind` or `plugin`), fed by the matcher `matcher` (an id) and judging fixes with `monitor`."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(..., pattern=ID_PATTERN, description="name of this instance in metrics and files")
    kind: str | None = Field(None, description="estimator kind: gps_only, hdop_switch, ekf, pf or a name an installed plugin registers")
    plugin: str | None = Field(None, description="instead of kind: a plugin class 'package.module:Class' (installed or on PYTHONPATH)")
    matcher: str | None = Field(None, description="id of the matcher whose odometry it uses (default: the only one)")
    monitor: str | None = Field(None, description="GPS integrity monitor: a name or 'package.module:Class' (default: the kind's own)")
    monitor_params: dict = Field(default_factory=dict, description="the monitor's parameters")
    sensors: list[str] | None = Field(
        None,
        description="what it is fed: any of gnss, odometry, imu, compass (default: gnss and odometry; gps_only: gnss); "
        "imu and compass simulate the [imu] and [compass] sections' sensors",
    )
    params: dict = Field(default_factory=dict, description="the kind's parameters (see `riverbench scenarios show`)")

    @property
    def ref(self) -> str:
        """What fusion.create takes: the kind or the plugin path."""
        return self.kind or self.plugin or ""

    @property
    def sensors_used(self) -> tuple[str, ...]:
        """The sensors it is fed: `sensors`, or the default (GPS and odometry; GPS alone for gps_only)."""
        if self.sensors is not None:
            return tuple(self.sensors)
        return ("gnss",) if self.kind == "gps_only" else DEFAULT_SENSORS

    @model_validator(mode="after")
    def _resolve(self) -> EstimatorSpec:
        _check_ref("estimator", self.id, self.kind, self.plugin)
        model = fusion.params_model(self.ref)
        where = f"estimator {self.id!r} ({self.ref})"
        for key in ("matcher", "monitor", "monitor_params", "sensors"):
            if key in self.params:
                raise ValueError(f"{where}: set {key!r} on the estimator, not in its params")
        if "seed" in self.params:
            raise ValueError(f"{where}: params.seed: every component takes the scenario's top-level seed; set 'seed' there")
        monitor = self.monitor or model.model_fields["monitor"].default
        try:  # a combined monitor's members' parameters too, which its own model keeps as plain tables
            self.monitor_params = fusion.monitors.validated(monitor, self.monitor_params).model_dump(mode="json")
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        self.monitor = monitor
        given = {"sensors": self.sensors} if self.sensors is not None else {}
        full = _validated(model, {**self.params, "monitor": monitor, "monitor_params": self.monitor_params, **given}, where)
        if self.sensors is not None:
            self.sensors = list(full["sensors"])
        self.params = {k: v for k, v in full.items() if k not in ("matcher", "monitor", "monitor_params", "seed", "sensors")}
        return self

    def build(self, seed: int, templates: Cn0Templates | None = None):
        """A fresh fusion Estimator with these settings; a random one (pf) draws from the scenario's seed. `templates`:
        the receiver's C/N0 templates, shared by the run's estimators (fusion.monitors.create)."""
        seeded = {"seed": seed} if "seed" in fusion.params_model(self.ref).model_fields else {}
        sensors = {"sensors": tuple(self.sensors)} if self.sensors is not None else {}
        return fusion.create(
            self.ref,
            matcher=self.matcher or "none",
            monitor=self.monitor,
            monitor_params=self.monitor_params,
            **self.params,
            **seeded,
            **sensors,
            templates=templates,
        )


def _check_ref(what: str, cid: str, kind: str | None, plugin: str | None) -> None:
    """Exactly one of kind (a name) and plugin (a 'package.module:Class' path), or a ValueError naming both."""
    where = f"{what} {cid!r}"
    if kind is not None and plugin is not None:
        raise ValueError(f"{where}: give kind or plugin, not both (kind = {kind!r}, plugin = {plugin!r})")
    if kind is None and plugin is None:
        raise ValueError(f"{where}: give kind (a registered {what} name) or plugin (a class 'package.module:Class')")
    if kind is not None and is_plugin_path(kind):
        raise ValueError(f"{where}: kind {kind!r} is a class path: write plugin = {kind!r}")
    if plugin is not None and not is_plugin_path(plugin):
        raise ValueError(f"{where}: plugin {plugin!r} is not a class path 'package.module:Class' (a registered name goes in kind)")


class Control(BaseModel):
    """How the vessel moves. `open_loop`: it follows the route exactly, whatever the estimators
    believe. `closed_loop`: the WAM-V model driven by the baseline autopilot, steering on the pose
    of the estimator `steer_on` (or on the truth, the reference), until the end of the stretch, a
    collision or the time limit. Its heading comes from the boat's compass by default, as on every
    ASV (GPS course over ground, gps_only's yaw, cannot close a heading loop). Clearance and
    cross-track metrics are kept in both modes."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["open_loop", "closed_loop"] = Field("open_loop", description="open_loop or closed_loop")
    steer_on: str = Field("truth", description="closed loop: id of the estimator the autopilot steers on, or 'truth'")
    heading: Literal["compass", "estimator"] = Field(
        "compass", description="closed loop: the heading the autopilot steers on: the boat's compass (AHRS) or the estimator's yaw"
    )
    gyro_sigma_dps: float = Field(
        0.3,
        ge=0,
        description="closed loop: white noise of the autopilot's gyro yaw rate (1-sigma, deg/s); its heading is a magnetic compass "
        "unit's with the scenario's [compass] figures (sim.compass.Ahrs)",
    )
    autopilot: AutopilotConfig = Field(default_factory=AutopilotConfig, description="gains of the LOS autopilot")
    dynamics: WamvDynamics = Field(default_factory=WamvDynamics, description="the WAM-V 16 manoeuvring model")
    current_enu_mps: tuple[float, float] = Field((0.0, 0.0), description="closed loop: uniform water current (east, north), m/s")
    time_limit_factor: float = Field(2.0, gt=1.0, description="closed loop: the run gives up after this multiple of the stretch's open-loop time")
    clearance_threshold_m: float = Field(
        3.0, ge=0, description="vessel.time_below_threshold_s counts the time the hull is closer than this to a structure"
    )


class IntegrityConfig(BaseModel):
    """How the estimators' protection levels are scored: against which alert limit."""

    model_config = ConfigDict(extra="forbid")
    alert_limit_m: float = Field(
        10.0,
        gt=0,
        allow_inf_nan=False,
        description="horizontal alert limit, m: an epoch whose protection level is below it is available; one whose error "
        "exceeds it while the level said below is hazardous [10 m: IMO Resolution A.1046(27)'s alert limit for inland "
        "waterways' navigation (10 m at 99.5 % accuracy 5 m) and for ports' approaches (25 m, 10 m accuracy)]",
    )


class FastVariant(BaseModel):
    """What `--fast` (riverbench run, sweep, suite) runs instead: a shorter stretch with its own expectations."""

    model_config = ConfigDict(extra="forbid")

    stretch: Stretch = Field(..., description="the short stretch")
    expect: list[str] = Field(default_factory=list, description="expectations on the short stretch")
    goals: list[str] = Field(default_factory=list, description="goals on the short stretch (see Scenario.goals)")

    @field_validator("expect", "goals")
    @classmethod
    def _parse(cls, value: list[str]) -> list[str]:
        return [Expectation.parse(v).text for v in value]


def default_lists() -> dict[str, list[dict]]:
    """The matchers and estimators a scenario has when it names none, as they would be written in TOML."""
    return {
        "matchers": [{"id": "gicp", "kind": "gicp"}],
        "estimators": [{"id": k, "kind": k} | ({} if k == "gps_only" else {"matcher": "gicp"}) for k in fusion.built_in()],
    }


def _default_matchers() -> list[MatcherSpec]:
    return [MatcherSpec(**m) for m in default_lists()["matchers"]]


def _default_estimators() -> list[EstimatorSpec]:
    return [EstimatorSpec(**e) for e in default_lists()["estimators"]]


class Scenario(BaseModel):
    """One bench scenario: world, stretch, vessel, sensors, faults, what is under test and what it must achieve."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(..., pattern=r"^[A-Za-z0-9_.-]+$", description="scenario name (run directories and reports)")
    description: str = Field("", description="one line: what this scenario tests")
    seed: int = Field(0, ge=0, description="seed of every random draw (vessel motion, LiDAR noise, GNSS errors)")
    world: str = Field("charles_river", description="a world preset (worlds.available()) or a mesh file")
    world_params: dict = Field(default_factory=dict, description="the preset's own parameters (or a mesh file's route etc.)")
    stretch: Stretch = Field(default_factory=Stretch, description="the part of the route to run")
    vessel: TrajectoryConfig = Field(default_factory=TrajectoryConfig, description="sim.Trajectory parameters")
    lidar: HDL32EConfig = Field(default_factory=HDL32EConfig, description="sim.HDL32E parameters (blinding is here)")
    gnss: GnssConfig = Field(default_factory=GnssConfig, description="sim.GnssReceiver parameters (forced outages and biases are here)")
    control: Control = Field(default_factory=Control, description="open loop or closed loop")
    traffic: TrafficConfig | None = Field(None, description="other vessels moving on the river (none by default: a static world)")
    imu: ImuConfig | None = Field(
        None, description="sim.imu: the IMU (a datasheet preset and overrides); simulated when an estimator's sensors include imu"
    )
    compass: CompassConfig | None = Field(
        None,
        description="sim.magnetic_compass: the magnetic compass and the steel's disturbance; simulated when an estimator's sensors include compass",
    )
    integrity: IntegrityConfig = Field(default_factory=IntegrityConfig, description="the alert limit the protection levels are scored against")
    matchers: list[MatcherSpec] = Field(default_factory=_default_matchers, description="scan matchers under test")
    estimators: list[EstimatorSpec] = Field(default_factory=_default_estimators, description="estimators under test")
    expect: list[str] = Field(
        default_factory=list,
        description="'metric op value' over dotted paths of metrics.json: the regression bounds (a baseline's spread derives "
        "them); a run that misses one fails (exit 1)",
    )
    goals: list[str] = Field(
        default_factory=list,
        description="'metric op value' like expect: the product's promises (an issue's targets), reported met or not in "
        "metrics.json, the report and docs/results.md, never re-derived from a baseline; a missed goal is a shortfall of "
        "the algorithms shown in plain sight, not a failed run",
    )
    fast: FastVariant | None = Field(None, description="the short variant `--fast` runs (run, sweep, suite)")
    command_matchers: list[CommandSpec] = Field(
        default_factory=list,
        exclude=True,
        description="the [[matchers]] of kind 'command' (scenarios.spec.command), gathered here at load and written back there",
    )
    command_estimators: list[CommandSpec] = Field(
        default_factory=list,
        exclude=True,
        description="the [[estimators]] of kind 'command', gathered here at load and written back there",
    )

    @model_validator(mode="before")
    @classmethod
    def _prepare(cls, data):
        """Reject per-section seeds; give estimators the boat's real mount and antenna unless they set their own."""
        if not isinstance(data, dict):
            return data
        data = _gather_commands(data)
        for section in SEEDED_SECTIONS:
            if isinstance(data.get(section), dict) and "seed" in data[section]:
                raise ValueError(f"{section}.seed: every component takes the scenario's top-level seed; set 'seed' there")
        try:
            mount = _mount_matrix(TrajectoryConfig.model_validate(data.get("vessel", {})))
            antenna = list(GnssConfig.model_validate(data.get("gnss", {})).antenna_offset_m)
        except (ValueError, TypeError):
            return data  # the section's own validation names the problem
        raw = data.get("estimators", default_lists()["estimators"])
        if isinstance(raw, list) and all(isinstance(e, dict) for e in raw):
            data = {**data, "estimators": [{**e, "params": {"mount": mount, "antenna": antenna, **_field_known(e, data)}} for e in raw]}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> Scenario:
        if self.world in worlds.available():
            try:
                self.world_params = worlds.resolve_params(self.world, **self.world_params)
            except ValueError as exc:
                raise ValueError(f"world_params: {exc}") from None
        elif not Path(self.world).suffix:
            raise ValueError(f"world: unknown world {self.world!r}; available: {', '.join(worlds.available())} (or a mesh file)")
        commands = [c.id for c in [*self.command_matchers, *self.command_estimators]]
        _unique("matchers and estimators", [m.id for m in self.matchers] + [e.id for e in self.estimators] + commands + ["groundtruth"])
        matcher_ids = [m.id for m in self.matchers]
        for est in self.estimators:
            if est.matcher in [c.id for c in self.command_matchers]:
                raise ValueError(
                    f"estimators.{est.id}.matcher: {est.matcher!r} is a command, whose trajectory comes back after the run; "
                    "an estimator takes a built-in or plugin matcher's odometry"
                )
            if est.kind == "gps_only":
                est.matcher = None
                continue
            if est.matcher is None:
                if len(matcher_ids) != 1:
                    raise ValueError(f"estimators.{est.id}.matcher: name one of the matchers ({', '.join(matcher_ids) or 'none defined'})")
                est.matcher = matcher_ids[0]
            elif est.matcher not in matcher_ids:
                raise ValueError(f"estimators.{est.id}.matcher: no matcher with id {est.matcher!r} (have {', '.join(matcher_ids) or 'none'})")
        self._inertial_sections()
        steer = self.control.steer_on
        if self.control.mode == "closed_loop" and steer != "truth" and steer not in [e.id for e in self.estimators]:
            raise ValueError(
                f"control.steer_on: no estimator with id {steer!r} (have {', '.join(e.id for e in self.estimators) or 'none'}, or 'truth')"
            )
        ids = {
            "estimators": {e.id for e in [*self.estimators, *self.command_estimators]},
            "matchers": {m.id for m in [*self.matchers, *self.command_matchers]},
        }
        self.expect = [Expectation.parse(text, ids).text for text in self.expect]
        # goals are the library's promises about its own stack: a variant that drops a component they name (a study
        # setup, --set estimators=[...]) keeps them, judged n/a there (nothing to measure), so their ids are not checked
        self.goals = [Expectation.parse(text).text for text in self.goals]
        if self.fast is not None:
            self.fast.expect = [Expectation.parse(text, ids).text for text in self.fast.expect]
            self.fast.goals = [Expectation.parse(text).text for text in self.fast.goals]
        return self

    def _inertial_sections(self) -> None:
        """An estimator fed imu or compass gets the sensor simulated ([imu] / [compass], default when absent); their rates
        must give whole samples per LiDAR revolution."""
        used = {s for e in self.estimators for s in e.sensors_used}
        if "imu" in used and self.imu is None:
            self.imu = ImuConfig()
        if "compass" in used and self.compass is None:
            self.compass = CompassConfig()
        revolution = 1.0 / self.lidar.rate_hz
        if self.imu is not None:
            samples_per_period(self.imu.rate_hz, revolution)
        if self.compass is not None:
            try:
                samples_per_period(self.compass.rate_hz, revolution)
            except ValueError as exc:
                raise ValueError(str(exc).replace("imu.rate_hz", "compass.rate_hz")) from None

    # ---- derived ------------------------------------------------------------------------------
    def resolved(self) -> dict:
        """Every field with its default filled in, json-able (None left out: TOML has no null)."""
        data = _drop_none(self.model_dump(mode="json"))
        for section in SEEDED_SECTIONS:
            data[section].pop("seed", None)
        for section, commands in (("matchers", self.command_matchers), ("estimators", self.command_estimators)):
            data[section] += [_drop_none(c.model_dump(mode="json")) for c in commands]
        return data

    @property
    def commands(self) -> list[tuple[str, CommandSpec]]:
        """Every component of kind 'command' with its section of metrics.json ('matchers' or 'estimators')."""
        return [("matchers", c) for c in self.command_matchers] + [("estimators", c) for c in self.command_estimators]

    @property
    def hash(self) -> str:
        """Stable identity of what runs: a digest of the resolved scenario without name and description."""
        data = {k: v for k, v in self.resolved().items() if k not in ("name", "description", "fast", "goals")}
        return hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]

    @property
    def setup_hash(self) -> str:
        """Identity of what is simulated and measured: the hash without the expectations, which judge the metrics but
        never move them (what a baseline records: re-bounding an expectation leaves its runs comparable)."""
        data = {k: v for k, v in self.resolved().items() if k not in ("name", "description", "fast", "expect", "goals")}
        return hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]

    def expectations(self) -> list[Expectation]:
        return [Expectation.parse(text) for text in self.expect]

    def goal_checks(self) -> list[Expectation]:
        """The goals, parsed: judged like expectations, reported apart (met or not), never failing a run."""
        return [Expectation.parse(text) for text in self.goals]

    def fast_variant(self) -> Scenario:
        """The scenario `suite --fast` runs: its [fast] stretch and expectations, or itself without one (`run --fast` and
        `sweep --fast` refuse that: scenarios.spec.library.load_fast)."""
        if self.fast is None:
            return self
        data = self.resolved()
        data["stretch"] = self.fast.stretch.model_dump(exclude_none=True)
        data["expect"] = list(self.fast.expect)
        data["goals"] = list(self.fast.goals)
        data.pop("fast")
        return Scenario.model_validate(data)

    def matcher_spec(self, matcher_id: str) -> MatcherSpec:
        return next(m for m in self.matchers if m.id == matcher_id)


def _gather_commands(data: dict) -> dict:
    """The raw data with the [[matchers]] and [[estimators]] of kind 'command' moved to command_matchers and
    command_estimators (the built-ins' validation never sees them)."""
    out = dict(data)
    for section in ("matchers", "estimators"):
        items = data.get(section)
        if not isinstance(items, list) or not any(isinstance(i, dict) and i.get("kind") == COMMAND for i in items):
            continue
        out[section] = [i for i in items if not (isinstance(i, dict) and i.get("kind") == COMMAND)]
        out[f"command_{section}"] = [_command(section, i) for i in items if isinstance(i, dict) and i.get("kind") == COMMAND]
    return out


def _command(section: str, item: dict) -> CommandSpec:
    """A command component validated, a bad field one line naming it as the scenario file does: {section}.{id}."""
    try:
        return CommandSpec.model_validate(item)
    except ValidationError as exc:
        raise ValueError(validation_message(exc, f"{section}.{item.get('id', '?')}")) from None


def _field_known(estimator: dict, data: dict) -> dict:
    """An estimator's params; one fed the compass knows the undisturbed field of the [compass] section unless it sets its own."""
    params = dict(estimator.get("params") or {})
    if "compass" not in (estimator.get("sensors") or ()):
        return params
    try:
        takes_inertial = "inertial" in fusion.params_model(estimator.get("kind") or estimator.get("plugin") or "").model_fields
    except (ValueError, KeyError, ImportError, AttributeError):
        return params  # an unknown kind: the estimator's own validation names it
    if not takes_inertial:
        return params
    try:
        compass = CompassConfig.model_validate(data.get("compass") or {})
    except (ValueError, TypeError):
        return params  # the section's own validation names the problem
    inertial = params.get("inertial") or {}
    if isinstance(inertial, dict):
        params["inertial"] = {"field_ut": compass.intensity_ut, "dip_deg": compass.inclination_deg, **inertial}
    return params


def _drop_none(value):
    """value with every None (at any depth, also in plain-dict params) left out."""
    if isinstance(value, dict):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_drop_none(v) for v in value]
    return value


def _mount_matrix(vessel: TrajectoryConfig) -> list[list[float]]:
    """base_link<-lidar as nested lists (what an estimator's `mount` parameter takes)."""
    return mount_matrix(vessel).tolist()


def _unique(what: str, ids: list[str]) -> None:
    seen = set()
    for i in ids:
        if i in seen:
            raise ValueError(f"{what}: id {i!r} is used twice" if i != "groundtruth" else f"{what}: id 'groundtruth' is reserved")
        seen.add(i)


def _validated(model: type[BaseModel], params: dict, where: str) -> dict:
    """params validated by `model`, every default filled in (json-able); a bad key is a one-line ValueError."""
    try:
        return model.model_validate(params).model_dump(mode="json")
    except ValidationError as exc:
        raise ValueError(validation_message(exc, where)) from None


__all__ = ["Control", "EstimatorSpec", "FastVariant", "MatcherSpec", "Scenario", "Stretch"]
