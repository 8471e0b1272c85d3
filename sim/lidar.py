"""Ray-cast Velodyne HDL-32E: real firing geometry and timing, motion distortion, range noise and
quantisation, water absorption, detection probability by material and range, mixed pixels at depth
edges (sim.beam), near-range blanking, intensity and self-occlusion."""

from __future__ import annotations

from typing import Literal

import numpy as np
import open3d as o3d
from pydantic import BaseModel, ConfigDict, Field, model_validator

from riverbench.rng import stream
from sim.beam import edge_sides, footprint_offsets, mix
from sim.foliage import crown_echo_ranges
from sim.lidar_traffic import MoverRays
from sim.scan import POINT_DTYPE, Scan
from sim.scene import Scene, split
from sim.traffic import Traffic
from worlds.world import World

# Vertical angle of each laser in firing (laser-id) order, HDL-32E user's manual: the most
# downward laser fires first, then the lower and upper banks interleave.
HDL32E_ELEVATION_DEG = np.array(
    [
        -30.67,
        -9.33,
        -29.33,
        -8.00,
        -28.00,
        -6.67,
        -26.67,
        -5.33,
        -25.33,
        -4.00,
        -24.00,
        -2.67,
        -22.67,
        -1.33,
        -21.33,
        0.00,
        -20.00,
        1.33,
        -18.67,
        2.67,
        -17.33,
        4.00,
        -16.00,
        5.33,
        -14.67,
        6.67,
        -13.33,
        8.00,
        -12.00,
        9.33,
        -10.67,
        10.67,
    ]
)
LASER_INTERVAL_S = 1.152e-6  # time between two consecutive lasers of a firing sequence
FIRING_CYCLE_S = 46.080e-6  # one firing sequence of all 32 lasers plus recharge
# The exact trajectory is evaluated every POSE_KNOT_FIRINGS firings (0.37 ms) and interpolated
# linearly in between: on a smooth vessel motion the error is below a micrometre and 1e-8 rad.
POSE_KNOT_FIRINGS = 8


def detection_constant(range_10pct_m: float) -> float:
    """k of `detection_probability` such that a 10%-reflective target at normal incidence at range_10pct_m is
    detected 90% of the time."""
    return float(-np.log(0.1) * range_10pct_m**2 / 0.1)


def detection_probability(power: np.ndarray, k: float, dropout_rate: float = 0.0) -> np.ndarray:
    """Probability that a return of power ~ reflectivity * cos(incidence) / r^2 is reported: 1 - exp(-k * power),
    near 1 for strong returns and falling as the power nears the detector's threshold (~1/k), times the share
    `dropout_rate` lost at random."""
    return (1.0 - dropout_rate) * -np.expm1(-k * np.asarray(power))


class HDL32EConfig(BaseModel):
    """Sensor parameters; defaults from the HDL-32E datasheet unless noted."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    rate_hz: float = Field(10.0, ge=5.0, le=20.0, description="rotation rate (the sensor allows 5-20 Hz)")
    range_noise_m: float = Field(0.02, ge=0, description="1-sigma Gaussian range noise (HDL-32E datasheet: range accuracy < 2 cm, typical)")
    range_resolution_m: float = Field(0.002, ge=0, description="range quantum of the data packets (user's manual: 2 mm increments); 0 = none")
    min_range_m: float = Field(
        1.0,
        gt=0,
        description="near-range blanking: returns closer are not reported (MAVS HDL-32E model, hdl32e.cpp: 1 m; "
        "the ROS velodyne driver's 32e launch drops < 0.4 m)",
    )
    max_range_m: float = Field(100.0, gt=0, description="returns beyond this are dropped (user's manual: usable returns up to 100 m)")
    range_10pct_m: float = Field(
        70.0,
        gt=0,
        description="range at which a 10%-reflective target at normal incidence is detected 90% of the time; detection is "
        "1 - exp(-k * reflectivity * cos(incidence) / r^2), so a 20% target is at 90% at 99 m (datasheet: 80-100 m range)",
    )
    dropout_rate: float = Field(0.01, ge=0, le=1, description="share of otherwise valid returns randomly lost")
    water_return_prob: float = Field(0.05, ge=0, le=1, description="probability of a water return at normal incidence (specular, absorbing)")
    water_return_exponent: float = Field(6.0, ge=0, description="water return probability falls as cos(incidence)**exponent")
    attenuation_per_m: float = Field(5e-4, ge=0, description="one-way atmospheric extinction on intensity")
    beam_divergence_mrad: float = Field(
        3.3,
        ge=0,
        le=20,
        description="full horizontal divergence of each laser, mrad (MAVS HDL-32E model, Mississippi State Univ., "
        "src/sensors/lidar/hdl32e.cpp: 3.3 x 0.7 mrad spot); 0 = a pencil beam, no mixed pixels",
    )
    footprint_samples: int = Field(3, ge=3, le=15, description="rays across a beam's footprint where it may straddle a depth edge (sim.beam)")
    edge_gap_m: float = Field(0.2, gt=0, description="azimuth neighbours' range difference that marks a depth edge, m (sim.beam)")
    foliage_echo: Literal["facets", "leaves"] = Field(
        "facets",
        description="where a return from a tree crown comes from: 'facets' (default), the hit on the world's 1.5 m "
        "leaf-cluster facets, which repeats from revolution to revolution like a solid surface's; 'leaves', a depth into the "
        "crown drawn afresh for every ray (Beer-Lambert gap probability, sim.foliage), as if every revolution met unrelated "
        "leaves. The two bracket a real crown: a real HDL-32E's rough returns, standing still, repeat within 0.3 m for 83% "
        "(benchmarks/foliage_echo.py; docs/models.md 'Foliage echoes')",
    )
    start_azimuth_deg: float = Field(180.0, description="azimuth (from lidar x, CCW) where a revolution starts")
    self_occlusion: bool = Field(True, description="rays that hit the vessel's own hull and mast return nothing")
    blinding: list[tuple[float, float]] = Field(
        default_factory=list, description="intervals [t0, t1] s: revolutions starting inside lose most points"
    )
    blinding_keep: float = Field(0.05, ge=0, le=1, description="share of points a blinded revolution keeps")
    seed: int = Field(0, description="seed of the noise, drop-out and blinding draws")

    @model_validator(mode="after")
    def _ranges_ordered(self) -> HDL32EConfig:
        if self.min_range_m >= self.max_range_m:
            raise ValueError(f"min_range_m ({self.min_range_m}) must be below max_range_m ({self.max_range_m})")
        return self


class HDL32E:
    """Velodyne HDL-32E model. `scan(world, trajectory, t0)` casts the revolution starting at t0."""

    elevation_deg = HDL32E_ELEVATION_DEG

    def __init__(self, rate_hz: float = 10.0, range_noise_m: float = 0.02, seed: int = 0, **more):
        self.config = HDL32EConfig(rate_hz=rate_hz, range_noise_m=range_noise_m, seed=seed, **more)
        cfg = self.config
        self.revolution_s = 1.0 / cfg.rate_hz
        self.n_firings = int(self.revolution_s / FIRING_CYCLE_S)
        self.azimuth_step_deg = 360.0 * cfg.rate_hz * FIRING_CYCLE_S
        laser = np.arange(32)
        # time of every ray since the revolution start, (n_firings, 32)
        self.ray_time = np.arange(self.n_firings)[:, None] * FIRING_CYCLE_S + laser[None, :] * LASER_INTERVAL_S
        # The head spins clockwise seen from above, so azimuth (CCW from x) decreases with time.
        azimuth = np.deg2rad(cfg.start_azimuth_deg) - 2.0 * np.pi * cfg.rate_hz * self.ray_time
        elevation = np.deg2rad(self.elevation_deg)[None, :]
        self.ray_dir = np.stack(
            [
                np.cos(elevation) * np.cos(azimuth),
                np.cos(elevation) * np.sin(azimuth),
                np.broadcast_to(np.sin(elevation), azimuth.shape),
            ],
            axis=-1,
        )
        self._ray_dir32 = self.ray_dir.astype(np.float32)
        self._azimuth, self._elevation = azimuth, np.broadcast_to(elevation, azimuth.shape)
        self._footprint = footprint_offsets(cfg.beam_divergence_mrad * 1e-3, cfg.footprint_samples)
        firing = np.arange(self.n_firings + 1)
        knot_firing = np.r_[firing[::POSE_KNOT_FIRINGS], firing[-1]]
        self._knot_t = knot_firing * FIRING_CYCLE_S
        self._knot_index = np.minimum(firing // POSE_KNOT_FIRINGS, len(self._knot_t) - 2)
        self._knot_frac = (firing * FIRING_CYCLE_S - self._knot_t[self._knot_index]) / np.diff(self._knot_t)[self._knot_index]
        self._mover_rays = MoverRays(self.ray_dir, azimuth, knot_firing, FIRING_CYCLE_S)
        self._detect_k = detection_constant(cfg.range_10pct_m)
        self._occlusion: dict[bytes, np.ndarray] = {}

    def scan(self, world: World | Scene, trajectory, t0: float) -> Scan:
        """Cast the revolution starting at t0 over `world` (a World, or a Scene with traffic: each mover where
        it was at each ray's firing time) from the vessel moving on `trajectory`."""
        cfg = self.config
        if not np.isfinite(t0):
            raise ValueError(f"lidar: scan start time is not finite ({t0})")
        world, traffic = split(world)
        knots, poses = self._poses(trajectory, t0)
        rays = self._rays(poses)
        hit = world.raycasting_scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        t_hit = hit["t_hit"].numpy()
        # incidence for every ray in one pass: cheaper than gathering normals and directions
        cos_all = np.abs(np.einsum("ij,ij->i", hit["primitive_normals"].numpy(), rays[:, 3:]))
        primitive = hit["primitive_ids"].numpy()
        movers_hit = None
        if traffic:
            movers_hit = self._mover_rays.cast(traffic, t0, knots, poses, t_hit, cos_all, cfg.max_range_m)
            primitive[movers_hit[0]] = 0  # any valid face: _surfaces relabels these rays
        visible = self._visible(trajectory)
        foliage_rng = stream(cfg.seed, f"sim.lidar.foliage@{t0:.9f}") if cfg.foliage_echo == "leaves" and len(world.crowns) else None
        if foliage_rng is not None:
            self._echo_from_leaves(world, rays, t_hit, primitive, foliage_rng, None if movers_hit is None else movers_hit[0])
        valid = (t_hit <= cfg.max_range_m) & visible
        mixed, mixed_range, mixed_power, mixed_part = self._mixed(world, poses, t_hit, valid, visible, primitive, cos_all, movers_hit, foliage_rng)
        is_mixed = np.zeros_like(valid)
        is_mixed[mixed] = True
        ray_index = np.flatnonzero(valid | is_mixed)
        at_mixed = is_mixed[ray_index]
        at_plain = ~at_mixed
        plain = ray_index[at_plain]
        part = np.zeros(len(ray_index), dtype=np.uint16)
        reflectivity = np.zeros(len(ray_index), dtype=np.float32)
        water = np.zeros(len(ray_index), dtype=bool)
        part[at_plain], reflectivity[at_plain], water[at_plain] = _surfaces(world, traffic, primitive, movers_hit, plain)
        rng_true = t_hit[ray_index].astype(np.float64)
        rng_true[at_mixed] = mixed_range
        cos_inc = cos_all[ray_index]

        # one stream per revolution, so a scan depends only on (seed, t0), not on the call order
        rng = stream(cfg.seed, f"sim.lidar@{t0:.9f}")
        draw = rng.random(len(rng_true))
        # Most rays hit water, which returns at most water_return_prob: only the water rays whose draw is below
        # the largest of their probabilities can return, so theirs are the only ones worth computing.
        might = water & (draw < _water_return(cos_inc[water].max(initial=0.0, keepdims=True), cfg))
        dry = ~water
        lit_rays = dry | might
        # returned power ~ reflectivity * cos(incidence) / r^2 (Lambertian target filling the beam)
        power = np.zeros(len(ray_index))
        power[lit_rays] = reflectivity[lit_rays] * cos_inc[lit_rays] / rng_true[lit_rays] ** 2
        power[at_mixed], part[at_mixed] = mixed_power, mixed_part
        p_return = np.zeros(len(ray_index))
        p_return[dry] = detection_probability(power[dry], self._detect_k, cfg.dropout_rate)
        p_return[might] = _water_return(cos_inc[might], cfg)
        if self._blinded(t0):
            p_return = p_return * cfg.blinding_keep
        returned = draw < p_return
        ranges = rng_true[returned] + cfg.range_noise_m * rng.standard_normal(int(returned.sum()))
        if cfg.range_resolution_m > 0:
            ranges = np.round(ranges / cfg.range_resolution_m) * cfg.range_resolution_m
        in_range = (ranges >= cfg.min_range_m) & (ranges <= cfg.max_range_m)

        ray_index = ray_index[returned][in_range]
        ranges = ranges[in_range]
        points = np.empty(len(ranges), dtype=POINT_DTYPE)
        local = self.ray_dir.reshape(-1, 3)[ray_index] * ranges[:, None]
        points["x"], points["y"], points["z"] = local.T
        # reflectivity * cos(incidence) of the lit surface (for a mixed pixel, its footprint's mean)
        lit = (power * rng_true**2)[returned][in_range]
        points["intensity"] = 100.0 * lit * np.exp(-2 * cfg.attenuation_per_m * ranges)
        points["ring"] = ray_index % 32
        points["time"] = self.ray_time.ravel()[ray_index]
        points["label"] = part[returned][in_range]
        return Scan(stamp=float(t0), points=points)

    def _mixed(
        self,
        world: World,
        poses: np.ndarray,
        t_hit: np.ndarray,
        valid: np.ndarray,
        visible: np.ndarray,
        primitive: np.ndarray,
        cos_all: np.ndarray,
        movers_hit: tuple[np.ndarray, np.ndarray] | None,
        foliage_rng: np.random.Generator | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Rays whose footprint straddles a depth edge and returns power (sorted), with their mixed range, mean
        power and label (sim.beam). Rays that hit a mover keep their plain return (the footprint sees the world only).
        With foliage_rng, footprint samples that meet a crown echo from a leaf at a random depth (sim.foliage)."""
        cfg = self.config
        none = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.float32), np.zeros(0, dtype=np.uint16)
        if cfg.beam_divergence_mrad == 0.0:
            return none
        before, after = (side.ravel() for side in edge_sides(t_hit.reshape(-1, 32), valid.reshape(-1, 32), cfg.edge_gap_m))
        edge = (before | after) & visible
        if movers_hit is not None:
            edge[movers_hit[0]] = False
        rays = np.flatnonzero(edge)
        if not len(rays):
            return none
        # cast only the samples on an edge's side; those on the other side lie on the centre's surface
        toward_before = self._footprint[None, :] > 0
        pair, k = np.nonzero(np.where(toward_before, before[rays, None], after[rays, None]))
        firing, laser = np.divmod(rays[pair], 32)
        azimuth = self._azimuth[firing, laser] + self._footprint[k]
        elevation = self._elevation[firing, laser]
        local = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], axis=-1).astype(np.float32)
        sub = np.empty((len(pair), 6), dtype=np.float32)
        sub[:, :3] = poses[firing, :3, 3]
        sub[:, 3:] = np.einsum("nij,nj->ni", poses[firing, :3, :3].astype(np.float32), local)
        hit = world.raycasting_scene.cast_rays(o3d.core.Tensor.from_numpy(sub))
        sub_t, sub_face = hit["t_hit"].numpy(), hit["primitive_ids"].numpy()
        if foliage_rng is not None:
            self._echo_from_leaves(world, sub, sub_t, sub_face, foliage_rng)
        width = 1 + len(self._footprint)
        t = np.repeat(t_hit[rays, None].astype(np.float64), width, axis=1)
        face = np.repeat(primitive[rays, None], width, axis=1)
        cos = np.repeat(cos_all[rays, None], width, axis=1)
        t[pair, 1 + k] = sub_t
        face[pair, 1 + k] = sub_face
        cos[pair, 1 + k] = np.abs(np.einsum("nj,nj->n", hit["primitive_normals"].numpy(), sub[:, 3:]))
        returns = t <= cfg.max_range_m
        returns[:, 0] &= valid[rays]
        face = np.where(returns, face, 0)
        returns &= ~world.face_is_water[face]
        power = np.where(returns, world.face_reflectivity[face] * cos / np.where(returns, t, 1.0) ** 2, 0.0)
        mean_power, mixed_range, strongest = mix(t, power)
        keep = mean_power > 0
        part = world.face_part[face[np.arange(len(rays)), strongest]]
        return rays[keep], mixed_range[keep], mean_power[keep].astype(np.float32), part[keep]

    def _echo_from_leaves(
        self, world: World, rays: np.ndarray, t: np.ndarray, face: np.ndarray, rng: np.random.Generator, skip: np.ndarray | None = None
    ) -> None:
        """Give every ray (rays (M, 6), t its hit range, face its hit face) that met a crown's facet the range of a leaf
        deeper in (sim.foliage), in place; rays in `skip` (those a mover took) keep theirs. Only hits within one crown's
        height beyond the range limit are drawn: a crown's chord can bring no farther one into range."""
        near = t <= self.config.max_range_m + 2.0 * world.crowns.radius.max()
        leafy = near & world.face_is_foliage[np.where(near, face, 0)]
        if skip is not None:
            leafy[skip] = False
        at = np.flatnonzero(leafy)
        t[at] = crown_echo_ranges(world.crowns, rays[at, :3], rays[at, 3:], t[at], rng)

    def dry_hits(self, world: World | Scene, trajectory, t0: float) -> int:
        """Rays of the revolution at t0 that meet a surface other than water within the reported range and clear the
        vessel: what a perfect detector would report, the bound the static world's geometry sets on `scan`'s count
        (mixed pixels aside)."""
        cfg = self.config
        static, _ = split(world)
        hit = static.raycasting_scene.cast_rays(o3d.core.Tensor.from_numpy(self.rays(trajectory, t0)))
        t_hit = hit["t_hit"].numpy()
        reached = (t_hit >= cfg.min_range_m) & (t_hit <= cfg.max_range_m) & self._visible(trajectory)
        face = np.where(reached, hit["primitive_ids"].numpy(), 0)
        return int((reached & ~static.face_is_water[face]).sum())

    def rays(self, trajectory, t0: float) -> np.ndarray:
        """(n_firings * 32, 6) float32 world rays (origin, unit direction) of the revolution at t0."""
        return self._rays(self._poses(trajectory, t0)[1])

    def _poses(self, trajectory, t0: float) -> tuple[np.ndarray, np.ndarray]:
        """World<-lidar at the pose knots (K + 1, 4, 4) and interpolated at every firing (n_firings + 1, 4, 4)."""
        knots = trajectory.lidar_poses(t0 + self._knot_t)
        if not np.isfinite(knots).all():
            raise ValueError(f"lidar: trajectory gave a NaN pose for the revolution at t0={t0:.3f} s")
        return knots, knots[self._knot_index] + self._knot_frac[:, None, None] * np.diff(knots, axis=0)[self._knot_index]

    def _rays(self, poses: np.ndarray) -> np.ndarray:
        """(n_firings * 32, 6) float32 world rays from the firing poses."""
        # The 32 lasers of one 46 us firing sequence share its origin (they are < 0.1 mm apart at
        # 2.5 m/s, below float32 resolution of world coordinates); direction and time are per laser.
        rays = np.empty((self.n_firings, 32, 6), dtype=np.float32)
        rays[..., :3] = poses[:-1, None, :3, 3]
        rays[..., 3:] = np.matmul(self._ray_dir32, poses[:-1, :3, :3].transpose(0, 2, 1).astype(np.float32))
        return rays.reshape(-1, 6)

    def _blinded(self, t0: float) -> bool:
        return any(a <= t0 <= b for a, b in self.config.blinding)

    def _visible(self, trajectory) -> np.ndarray:
        """(n_firings * 32,) rays that clear the vessel's own body; fixed to the sensor, so cast once per mount."""
        if not self.config.self_occlusion:
            return np.ones(self.ray_time.size, dtype=bool)
        key = trajectory.mount.tobytes() + trajectory.hull.vertices.tobytes()
        if key not in self._occlusion:
            hull = trajectory.hull.copy().apply_transform(np.linalg.inv(trajectory.mount))
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(
                o3d.core.Tensor(np.asarray(hull.vertices, dtype=np.float32)),
                o3d.core.Tensor(np.asarray(hull.faces, dtype=np.uint32)),
            )
            d = self.ray_dir.reshape(-1, 3)
            rays = np.concatenate([np.zeros_like(d), d], axis=1).astype(np.float32)
            t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
            self._occlusion[key] = ~np.isfinite(t_hit)
        return self._occlusion[key]


def _water_return(cos_incidence: np.ndarray, cfg: HDL32EConfig) -> np.ndarray:
    """Probability that a ray hitting water at this incidence cosine returns (specular, absorbing surface)."""
    return cfg.water_return_prob * cos_incidence**cfg.water_return_exponent


def _surfaces(
    world: World, traffic: Traffic, primitive: np.ndarray, movers_hit: tuple[np.ndarray, np.ndarray] | None, ray_index: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Label, reflectivity and water flag of each returned ray (ray_index, sorted) from the world face it hit, then,
    for the rays a mover hit first (movers_hit: sorted rays, mover index), mover i as label len(world.parts) + i."""
    face = primitive[ray_index]
    part, reflectivity, water = world.face_part[face], world.face_reflectivity[face], world.face_is_water[face]
    if movers_hit is not None:
        rays, mover = movers_hit
        at = np.minimum(np.searchsorted(ray_index, rays), len(ray_index) - 1)
        returned = ray_index[at] == rays if len(ray_index) else np.zeros(len(rays), dtype=bool)
        at, mover = at[returned], mover[returned]
        part[at] = len(world.parts) + mover
        reflectivity[at], water[at] = traffic.reflectivity[mover], False
    return part, reflectivity, water
