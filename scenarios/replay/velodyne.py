"""Which Velodyne made a capture: the sensor models velodyne_decoder decodes, their packets' timing and laser
geometry, and the model a packet stream is, from its factory bytes checked against what the data itself shows.

Every data packet (1206 bytes) ends with the factory bytes: the return mode (0x37 strongest, 0x38 last, 0x39 dual)
and the product id (0x21 HDL-32E, 0x22 VLP-16, 0x24 Puck Hi-Res, 0x28 VLP-32C, 0xA1 VLS-128 / Alpha Prime;
0x23 is VLP-32A or B, which velodyne_decoder cannot tell apart). Firmware does not always set them (an early
VLP-16 reports the HDL-32E's 0x21), so the stream is checked against the claimed model with three things the
packets measure on their own (`Evidence`):
- the time one packet spans, from consecutive packets' sensor clocks (12 blocks of the model's firing timing, half
  of that in dual-return mode, when blocks come in pairs of one firing);
- the rotation rate that gives with the azimuth step between blocks: every model spins at 300-1200 RPM;
- whether each block holds 16 lasers fired twice (channel j and j + 16 the same laser 55 us apart: nearly equal
  ranges) or 32 different lasers.
The claimed model is used when it fits all three. Otherwise, when exactly one model fits, the stream is decoded as
that model and the replay says so; VLP-16 and Puck Hi-Res send the same packets (only their lasers' elevations
differ, +-15 deg against +-10 deg), and a stream that fits both but claims neither is taken as the VLP-16, since
the Hi-Res reports its own 0x24. When none or several fit, or the sensor is one this bench does not decode (HDL-64E,
whose decoding needs the unit's own calibration; VLP-32A/B; Velarray), a one-line ValueError names it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np
import velodyne_decoder as vd
import yaml

DATA_BYTES = vd.PACKET_SIZE
POSITION_BYTES = vd.TELEMETRY_PACKET_SIZE
BLOCKS = 12
CHANNELS = 32
BLOCK = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("laser", [("distance", "<u2"), ("reflectivity", "u1")], (CHANNELS,))])
DATA = np.dtype([("block", BLOCK, (BLOCKS,)), ("stamp", "<u4"), ("return_mode", "u1"), ("product", "u1")])
UPPER_BANK, LOWER_BANK = 0xEEFF, 0xDDFF
RETURN_MODES = {0x37: "strongest", 0x38: "last", 0x39: "dual"}
DUAL = 0x39
STRONGEST = 0x37
TIMING_TOLERANCE = 0.03
"""Relative slack on a packet's measured time span and rotation rate (the manuals' timings are exact; the sensor
clock's microseconds and a motor's drift are not)."""
REPEAT_RATIO = 3.0
"""A block holds one laser twice when its channel pairs (j, j + 16) differ in range less than this many times the
same channel between consecutive blocks (measured: 0.6 on the VLP-16 capture, 430 on the HDL-32E one)."""
MIN_PAIRS = 200
"""Range pairs needed before the block layout is judged (fewer: a capture seeing almost nothing)."""


@dataclass(frozen=True)
class SensorModel:
    """A Velodyne model velodyne_decoder decodes: its product id, decoder model and calibration, lasers, a single-return
    packet's time span and the time between two block azimuths (user manuals), its spin range."""

    name: str
    product_id: int
    decoder: vd.Model
    calibration: str
    lasers: int
    packet_s: tuple[float, ...]
    azimuth_s: tuple[float, ...]
    rpm: tuple[float, float] = (300.0, 1200.0)

    def packet_spans(self, dual: bool) -> tuple[float, ...]:
        """The time one data packet spans in this return mode."""
        return tuple(p / 2 if dual else p for p in self.packet_s)

    def rotation_hz(self, azimuth_step_deg: float) -> tuple[float, ...]:
        """The rotation rate each timing variant gives to a measured azimuth step between blocks."""
        return tuple(azimuth_step_deg / 360.0 / s for s in self.azimuth_s)

    def decoder_config(self) -> vd.Config:
        """velodyne_decoder set for this model with its bundled VeloView calibration (every beam from the sensor's centre,
        as the simulator casts them), each scan stamped with its first packet's time."""
        return vd.Config(model=self.decoder, calibration=vd.get_bundled_calibration(self.calibration), timestamp_first_packet=True)

    @property
    def elevation_deg(self) -> np.ndarray:
        """Each laser's elevation (deg) by laser id (firing order), from velodyne_decoder's bundled calibration."""
        return calibration_elevations(self.calibration)

    @property
    def laser_of_ring(self) -> np.ndarray:
        """Laser id (firing order) of each ring as velodyne_decoder numbers them (by elevation, bottom-up)."""
        return np.argsort(self.elevation_deg, kind="stable").astype(np.uint16)


HDL32E_FIRING_S = 46.08e-6  # HDL-32E application note 63-9277 Rev D p.20: 32 x 1.152 us + 9.216 us recharge
PUCK_FIRING_S = 55.296e-6  # VLP-16 manual 63-9243 Rev E p.50, VLP-32C manual p.49: 16 x 2.304 us + 18.43 us recharge
VLS128_CHANNEL_S = (2.665e-6, 2.889e-6)  # VLS-128 / Alpha Prime: firmware 5.1.7.1 and 5.2.3.0+ (VeloView, velodyne_decoder)
MODELS = (
    SensorModel("HDL-32E", 0x21, vd.Model.HDL32E, "HDL-32E.yml", 32, (12 * HDL32E_FIRING_S,), (HDL32E_FIRING_S,)),
    SensorModel("VLP-16", 0x22, vd.Model.VLP16, "VLP-16.yml", 16, (24 * PUCK_FIRING_S,), (2 * PUCK_FIRING_S,)),
    SensorModel("Puck Hi-Res", 0x24, vd.Model.PuckHiRes, "Puck Hi-Res.yml", 16, (24 * PUCK_FIRING_S,), (2 * PUCK_FIRING_S,)),
    SensorModel("VLP-32C", 0x28, vd.Model.VLP32C, "VLP-32C.yml", 32, (12 * PUCK_FIRING_S,), (PUCK_FIRING_S,)),
    SensorModel(
        "VLS-128",
        0xA1,
        vd.Model.VLS128,
        "Alpha Prime.yml",
        128,
        tuple(3 * 20 * c for c in VLS128_CHANNEL_S),
        tuple(20 * c for c in VLS128_CHANNEL_S),
    ),
)
BY_ID = {m.product_id: m for m in MODELS}
BY_NAME = {m.name: m for m in MODELS}
UNSUPPORTED = {0x23: "a VLP-32A or VLP-32B (product id 0x23: velodyne_decoder cannot tell which)", 0x31: "a Velarray (product id 0x31)"}
SAME_PACKETS = ("VLP-16", "Puck Hi-Res")
"""Models whose packets cannot be told apart; a stream that fits both and claims neither is the first."""


@cache
def calibration_elevations(name: str) -> np.ndarray:
    """Elevation (deg) by laser id of one of velodyne_decoder's bundled calibration files."""
    text = (resources.files("velodyne_decoder.calibrations") / name).read_text()
    lasers = sorted(yaml.safe_load(text)["lasers"], key=lambda laser: laser["laser_id"])
    return np.degrees([laser["vert_correction"] for laser in lasers])


@dataclass(frozen=True)
class Evidence:
    """What a sample of data packets shows, whatever their factory bytes say."""

    packets: int
    product_id: int
    return_mode: int
    packet_s: float  # median time between consecutive packets on the sensor clock (NaN when it cannot be measured)
    azimuth_step_deg: float  # mean step between consecutive distinct block azimuths
    repeats: bool | None  # each block holds 16 lasers fired twice (None: too few returns to tell)
    lower_bank: bool  # some block carries the HDL-64E's lower-bank flag

    @property
    def dual(self) -> bool:
        return self.return_mode == DUAL

    def describe(self, *models: SensorModel) -> str:
        """The measured figures beside what each of `models` would give."""
        spans = ", ".join(f"{m.name}: {'/'.join(f'{s * 1e6:.0f}' for s in m.packet_spans(self.dual))}" for m in models)
        rates = ", ".join(f"{'/'.join(f'{r:.1f}' for r in m.rotation_hz(self.azimuth_step_deg))} Hz as {m.name}" for m in models)
        spin = f"{models[0].rpm[0] / 60:.0f}-{models[0].rpm[1] / 60:.0f} Hz"
        layout = {True: "16 lasers fired twice per block", False: "32 lasers per block", None: "block layout unknown"}[self.repeats]
        return f"{self.packet_s * 1e6:.0f} us per packet ({spans}), {self.azimuth_step_deg:.3f} deg per block ({rates}; they spin {spin}), {layout}"


def evidence(payloads: list[bytes], stamps_us: np.ndarray) -> Evidence:
    """The evidence of a sample of consecutive data packets (their payloads and unwrapped sensor times, us)."""
    data = np.frombuffer(b"".join(payloads), DATA)
    ids, counts = np.unique(data["product"], return_counts=True)
    modes, mode_counts = np.unique(data["return_mode"], return_counts=True)
    steps = np.diff(stamps_us)
    steps = steps[steps > 0]
    azimuth = data["block"]["azimuth"].astype(np.int64)
    block_steps = ((azimuth[:, 1:] - azimuth[:, :-1]) % 36000).ravel()
    block_steps = block_steps[(block_steps > 0) & (block_steps < 18000)]
    block_steps = block_steps[block_steps < 2 * np.median(block_steps)] if len(block_steps) else block_steps  # a packet lost between
    return Evidence(
        packets=len(data),
        product_id=int(ids[np.argmax(counts)]),
        return_mode=int(modes[np.argmax(mode_counts)]),
        packet_s=float(np.median(steps)) * 1e-6 if len(steps) else math.nan,
        azimuth_step_deg=float(np.mean(block_steps)) / 100.0 if len(block_steps) else math.nan,
        repeats=repeats(data),
        lower_bank=bool((data["block"]["flag"] == LOWER_BANK).any()),
    )


def repeats(data: np.ndarray) -> bool | None:
    """Whether channels j and j + 16 of a block are one laser fired twice (see REPEAT_RATIO); None with too few returns."""
    blocks = data["block"].reshape(-1)
    distinct = np.concatenate([[True], np.diff(blocks["azimuth"].astype(np.int64)) != 0])  # dual mode: the pair's first
    distance = blocks["laser"]["distance"][distinct & (blocks["flag"] == UPPER_BANK)].astype(np.float64)
    low, high = distance[:, :16], distance[:, 16:]
    pair = (low > 0) & (high > 0)
    now, after = distance[:-1], distance[1:]
    along = (now > 0) & (after > 0)
    if pair.sum() < MIN_PAIRS or along.sum() < MIN_PAIRS:
        return None
    within = np.median(np.abs(low - high)[pair] / low[pair])
    between = np.median(np.abs(now - after)[along] / now[along])
    return bool(within < REPEAT_RATIO * max(between, 1e-4))


def fits(model: SensorModel, seen: Evidence) -> bool:
    """Whether the packets can be `model`'s: their time span, rotation rate and block layout (unmeasured ones pass)."""
    if math.isfinite(seen.packet_s) and not any(abs(seen.packet_s / s - 1.0) <= TIMING_TOLERANCE for s in model.packet_spans(seen.dual)):
        return False
    low, high = (r / 60.0 for r in model.rpm)
    tolerant = lambda hz: low * (1 - TIMING_TOLERANCE) <= hz <= high * (1 + TIMING_TOLERANCE)
    if math.isfinite(seen.azimuth_step_deg) and not any(tolerant(hz) for hz in model.rotation_hz(seen.azimuth_step_deg)):
        return False
    return seen.repeats is None or seen.repeats == (model.lasers == 16)


@dataclass(frozen=True)
class Identified:
    """The model to decode as, and what the replay says about how it was found."""

    model: SensorModel
    note: str = ""

    @property
    def factory_bytes(self) -> tuple[int, int]:
        """(return mode, product id) to give velodyne_decoder, which checks the product id against the model."""
        return STRONGEST, self.model.product_id


def identify(seen: Evidence, where: str) -> Identified:
    """The model the packets are (module docstring); a one-line ValueError for a sensor this bench does not decode."""
    claimed = BY_ID.get(seen.product_id)
    label = f"{claimed.name} (0x{seen.product_id:02X})" if claimed else f"product id 0x{seen.product_id:02X}"
    if seen.lower_bank and seen.product_id != BY_NAME["VLS-128"].product_id:  # the VLS-128's four banks carry it too
        raise ValueError(f"{where}: HDL-64E data (its blocks carry the lower-bank flag 0xDDFF): not supported (it needs the unit's own calibration)")
    if seen.product_id in UNSUPPORTED:
        raise ValueError(f"{where}: {UNSUPPORTED[seen.product_id]}: not supported")
    if claimed is not None and fits(claimed, seen):
        return Identified(claimed)
    timed = math.isfinite(seen.packet_s) and math.isfinite(seen.azimuth_step_deg)
    if claimed is not None and timed and fits(claimed, dataclasses.replace(seen, repeats=None)):
        # the timing and the rotation are measured physics; the layout test is a statistic of the scene's ranges, which a
        # scene can fool (riverbench's own 60 s export of dam_lock's chamber: channels j and j + 16 came out alike)
        return Identified(
            claimed,
            f"factory bytes say {label} and the packets' timing and rotation are its own, though the blocks "
            f"looked like 16 lasers fired twice (the scene's ranges can make channels j and j + 16 alike): {seen.describe(claimed)}",
        )
    candidates = [m for m in MODELS if fits(m, seen)]
    names = [m.name for m in candidates]
    if names == list(SAME_PACKETS):
        candidates = candidates[:1]
    if len(candidates) != 1:
        fitting = f"fit {', '.join(names)}" if names else "fit no supported model"
        raise ValueError(f"{where}: factory bytes say {label} but the packets {fitting}: {seen.describe(*([claimed] if claimed else MODELS))}")
    model = candidates[0]
    hi_res = f"; Puck Hi-Res sends the same packets but reports 0x{BY_NAME['Puck Hi-Res'].product_id:02X}" if model.name == SAME_PACKETS[0] else ""
    shown = seen.describe(*([claimed, model] if claimed else [model]))
    return Identified(model, f"factory bytes say {label}, but the packets are a {model.name}'s: {shown}; decoded as {model.name}{hi_res}")
