"""Monitor 'cn0': C/N0-based NLOS detection against an elevation template learned online from the receiver.

A signal that reaches the antenna only by reflection (NLOS) arrives weaker than a direct one at the
same elevation (reflection loss, typically 5-10 dB), and its pseudorange carries the extra path.
The receiver reports per satellite its elevation and C/N0 (NMEA GSV) and whether it used it (GSA),
so each used satellite's C/N0 can be compared with what a direct signal at that elevation gives.

Template: what a direct signal gives is a property of the receiver and antenna, so it is learned
from the receiver's own reports rather than configured: every tracked satellite of every screened
fix goes into a ring buffer per sin(elevation) bin; the direct signals are the upper part of each
bin's distribution (NLOS only ever lowers C/N0), so with a Gaussian jitter sigma the bin's
`mid_q` and `high_q` quantiles of the residual about the current line give sigma (their gap over
the normal quantiles' gap, pooled over bins by the median) and the direct mean (the `mid_q`
quantile minus its normal quantile times sigma). A weighted least-squares line through the bins'
direct means over sin(elevation) is the template; this is repeated `iterations` times so the
quantiles are taken about the line (removing the slope within a bin). The template is kept when
the host re-locks (reset): it calibrates the receiver, not the track.

Verdict: each used satellite's normalised deficit d = (template(el) - C/N0) / sigma; satellites
with d > gate_sigma look NLOS; a fix's deficit is the largest d among its used satellites. That largest of n direct
signals' jitters exceeds gate_sigma about n times as often as one does (16 used satellites: 5e-4 a fix at 4 sigma, once
in 7 minutes at 5 Hz, and each such fix then holds the next `hold_s` of fixes), so with `family_gate` each satellite is
tested at the level that keeps the fix's chance at gate_sigma's (Sidak 1967, JASA 62:626-633), and deficits are
reported in units of that level (over gate_sigma: over the fix's gate). The
receiver's navigation filter smooths its raw solutions, so an NLOS epoch's error lingers in the
fixes that follow for a few seconds after the reflected satellite is dropped (on charles_river 62
of the 63 fixes that the environment put > 5 m off without a used NLOS satellite were within 5.2 s
of one). The statistic is therefore the largest deficit over the last `hold_s` seconds, and the fix
is distrusted when it exceeds gate_sigma. Until `min_bins` bins hold `min_samples_per_bin`
samples the monitor cannot judge and trusts the fix (reason says it is learning), unless a receiver
profile (`profile_template`: the direct-signal line and jitter measured for this receiver and
antenna under open sky) stands in for the template until it is learned. Satellites with a
non-finite or non-positive C/N0 or elevation are skipped and named in the reason.

Weighed by the geometry: C/N0 alone cannot tell a reflection's loss from a tree crown's attenuation of a direct signal
(both 5-10 dB), but only a reflection adds path, and a satellite's range error moves the fix by its slope (the horizontal
shift of the receiver's least-squares fix per metre of range bias, fusion.monitors.satellite_geometry: elevation
weights, the larger of one clock's and one per constellation's). The suspects (deficit > gate_sigma) refuse the fix only when together they could
move it by more than `fault_m` were each reflected with `nlos_bias_m` cos(elevation) of extra path (a reflection off a
vertical wall 25 m away: `vertical_reflectors`); otherwise the fix is judged on the other satellites' deficits and the
reason names the suspects and the shift they could cause. A low satellite among many
barely moves the fix (charles_river: 14 deg among 17, 0.06 m/m, 3.1 m at 48.5 m), one under a deck among few moves it
much. The price: a reflection longer than `nlos_bias_m` on a satellite judged harmless moves the fix by more than
`fault_m`; the consistency monitor beside it in 'combined_cn0' sees that as a displacement the odometry did not make.

Several constellations and signals (`per_signal`): a receiver reports each system's signals at its
own level: the signals' specified minimum received powers differ (PRIOR_OFFSETS_DB, from the
systems' interface specifications), and receivers differ further in how they track and report
them. Each signal (system and signal name, sim.nmea.systems) expects the template plus its own
offset from GPS L1 C/A: its prior until `min_samples_per_signal` of its reports are buffered, then
learned from the recording itself as the template is (the `mid_q` quantile of its residuals about
the template less its normal quantile times sigma, relative to GPS L1 C/A's, or, with too few GPS
L1 C/A reports, to the most reported signal's, which keeps its prior), and so is its jitter (the
gap of its residuals' `mid_q` and `high_q` quantiles, pooled over all its satellites, so it also
holds the spread between them; never below the template's sigma). The template is learned from
every signal's reports less their offsets. A receiver that reports GPS L1 C/A only (the
simulator with `[gnss] constellations = ["GPS"]`) never uses an offset: its template, jitter and
verdicts are the single-template ones; the simulator's other systems sit at the priors' offsets.

Between satellites: direct signals do not all sit on one line. Satellites transmit at different
powers (GPS L1 C/A differs by a few dB between satellite blocks: Steigenberger, Thoelert and
Montenbruck 2018, J. Geodesy 92:609-624); a small antenna's gain varies with azimuth as well as
elevation; on a vessel the superstructure (mast, sails, cabin, crew) shadows parts of the sky; and
at low elevation the direct signal interferes with its reflection off the water, so its C/N0 moves
between 20 log10(1 + a) and 20 log10(1 - a) (a: the reflection's amplitude relative to the direct
one; a = 0.7 gives +4.6 to -10.5 dB) as the geometry and the antenna's height over the water change
(Bilich and Larson 2007, Radio Science 42, RS6003; Larson, Loefgren and Haas 2013, Adv. Space Res.
51:1301-1310). These last for minutes, so within one satellite's reports they are a level and its
fades, not jitter, and they lower C/N0 more often than they raise it: C/N0 separates reflected
from direct signals only statistically, at levels specific to the receiver, antenna and
installation (Groves, Jiang, Rudi and Strode 2013, ION GNSS+ 2013, 3231-3247; Strode and Groves
2016, GPS Solutions 20:399-412). When many satellites have passed through each bin (a long run, or
the simulator, whose satellites share one C/N0 model) the bins' quantiles hold this spread; when a
bin holds one or two satellites (a short log, a receiver at 1 Hz) they measure one satellite's
jitter, and ordinary direct signals look NLOS (a B&G Zeus2 chartplotter in open water on the
IJsselmeer, tests/data/nmea/gpsd/bundg_zeus_9.log: GPS PRN 29 at 11 deg elevation gives 46 dB-Hz,
PRN 8 at 12 deg 24-35 dB-Hz, each nearly constant over the log). So each satellite (system, signal
and number) also gets a level, the `mid_q` quantile of its buffered reports about the template
less its signal's offset (its direct level: like a bin's, the upper part of its reports, which
reflection, shadowing and fades only lower), once it holds `min_samples_per_satellite` of them.
When the levels' spread (the normal-consistent median absolute deviation, robust while fewer than
half of the satellites are NLOS throughout their buffered reports) exceeds the bins' sigma by more
than its own sampling error (`levels_z` standard errors), the bins see too few satellites, and
sigma becomes the same robust spread of all buffered reports with each satellite weighted equally,
which holds both the differences between satellites and each one's fades (never below the bins'
sigma). A sky whose direct signals share one level, as the simulator's do, does not switch: its
sigma, template and verdicts are the bins' ones (benchmarks/cn0_satellites.py compares them on the
library's simulated fixes). The price: where more than half of the tracked satellites have been
NLOS for as long as the buffers remember (minutes in a deep street canyon), their levels look like
spread between direct signals, sigma widens and fewer NLOS fixes are flagged.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Hashable
from functools import lru_cache

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.stats import norm

from fusion.monitors.base import FixContext, Monitor
from fusion.monitors.satellite_geometry import horizontal_slopes
from fusion.observation import FixObservation
from fusion.verdict import Verdict

RECEIVER_HALF_LIFE_S = 4.0
"""A consumer receiver's position filter halves a raw fault's effect on its output in about this long, s (hold_s's
figure): the decay of a held fault's allowance when hold_half_life_s is not set."""
REFERENCE = "GPS L1 C/A"
"""The signal every offset is relative to (a GPS-only receiver's only one)."""
MAD_TO_SIGMA = float(1.0 / norm.ppf(0.75))
"""The median absolute deviation of normal samples times this is their standard deviation (1.4826)."""
MAD_RELATIVE_SE = math.sqrt(1.0 / (2.0 * 0.3675))
"""Standard error of that standard deviation from n normal samples, times sqrt(n), over the standard deviation (1.166): the
median absolute deviation's asymptotic efficiency at the normal is 36.75 % (Rousseeuw and Croux 1993, JASA 88:1273-1283),
the sample standard deviation's variance sigma^2 / (2 n)."""
PRIOR_OFFSETS_DB = {
    "GPS L1 C/A": 0.0,
    "GPS L2C-M": -1.5,
    "GPS L2C-L": -1.5,
    "GPS L5-I": 0.6,
    "GPS L5-Q": 0.6,
    "GLONASS L1OF": -2.5,
    "GLONASS L2OF": -8.5,
    "Galileo E1-BC": 1.5,
    "Galileo E5a": 3.5,
    "Galileo E5b": 3.5,
    "BeiDou B1I": -4.5,
    "BeiDou B2I": -4.5,
    "QZSS L1 C/A": 0.0,
    "SBAS L1 C/A": -2.5,
}
"""Specified minimum received power of each signal less GPS L1 C/A's -158.5 dBW (IS-GPS-200N Table 3-Va), dB: GPS L2C -160
(IS-GPS-200N), L5 -157.9 per component (IS-GPS-705J); GLONASS L1OF -161, L2OF -167 (GLONASS ICD L1/L2 edition 5.1, 2008,
3.3.1.6); Galileo E1 (B+C) -157, E5a and E5b -155 (Galileo OS SIS ICD issue 2.1, 2023, 2.4.1); BeiDou B1I and B2I -163
(BDS-SIS-ICD-B1I-3.0 and -B2I-1.0, 2019/2013); QZSS L1 C/A -158.5 (IS-QZSS-PNT-005); SBAS L1 -161 (ICAO Annex 10 vol. I,
3.7.3.4). A prior only: receivers report C/N0 at their own levels (learned per signal from the recording)."""


class Cn0Params(BaseModel):
    """Parameters of the 'cn0' monitor: the elevation template learned online and the NLOS gate (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")
    bins: int = Field(9, ge=2, description="number of sin(elevation) bins over [0, 1] [9]")
    samples_per_bin: int = Field(
        600,
        ge=10,
        description="samples kept per bin [600: about 10 minutes of one satellite at 1 Hz, or a minute of a bin shared by a few satellites at 5 Hz]",
    )
    min_samples_per_bin: int = Field(40, ge=5, description="a bin counts once it holds this many samples [40]")
    min_bins: int = Field(3, ge=2, description="the template needs this many counting bins; until then fixes are trusted (learning) [3]")
    mid_q: float = Field(
        0.75,
        gt=0.5,
        lt=1.0,
        description="lower quantile of a bin's direct signals [0.75: with high_q the direct signals' upper part, robust "
        "to up to about a quarter of a bin's samples being NLOS]",
    )
    high_q: float = Field(
        0.9,
        gt=0.5,
        lt=1.0,
        description="upper quantile of a bin's direct signals, above mid_q [0.9: with mid_q the direct signals' upper "
        "part, robust to up to about a quarter of a bin's samples being NLOS]",
    )
    iterations: int = Field(2, ge=1, description="template fitting iterations (quantiles taken about the previous line) [2]")
    min_sigma_db: float = Field(0.5, gt=0, description="floor of the C/N0 jitter sigma, dB [0.5: receivers report C/N0 in whole dB]")
    gate_sigma: float = Field(
        4.0,
        gt=0,
        description="a used satellite whose C/N0 falls more than this many sigma below the template looks NLOS [4: a "
        "direct signal with Gaussian jitter exceeds it with probability 3e-5; a 1 dB jitter puts the gate at 4 dB, half "
        "a typical 8 dB reflection loss]; with family_gate, the level a fix of direct signals exceeds with that probability",
    )
    family_gate: bool = Field(
        True,
        description="the gate holds for the fix, not for each satellite: a fix is judged by the largest deficit among its "
        "n used satellites, and the largest of n direct signals' jitters exceeds gate_sigma n times as often as one "
        "does, so each is tested at the level that keeps the fix's chance at gate_sigma's (Sidak 1967, JASA "
        "62:626-633): 4.61 sigma for 16 satellites, 4.32 for 4 [True: library [fast] seeds 0-2 and the demo's seeds 0-4 "
        "at 384f007, 10 of 3,635 fixes the deficit refused fall under it, each 4.0-4.4 sigma on one epoch, all within 0.6 m "
        "and 9 of them on direct signals alone, and each had held the next 6 s of fixes (steel_bridge_compass seed 0: 31 "
        "of its 389, within 0.4 m); docs/models.md 'One gate per fix'. False: every satellite at gate_sigma, as before]",
    )
    hold_s: float = Field(
        6.0,
        ge=0,
        description="a deficit is held this long, s [6: a consumer receiver's filter halves a raw fault's effect on its "
        "output in about 4 s; 0 = no hold]",
    )

    hold_half_life_s: float | None = Field(
        None,
        gt=0,
        description="a held fault counts only while it could still move the fix by more than fault_m: its effect (how "
        "far its suspects could move the fix, nlos_bias_m) halves every this many s, as hold_s's receiver filter halves a "
        "raw fault's effect on its output [None: held for hold_s whatever its size. 4 (the receiver-filter figure) lowers "
        "the monitor's false alarms alone (9 library stretches, seeds 0 and 3: recall unchanged on all 18, false alarms "
        "down on 12, charles_river 0.145 -> 0.097) but in the fused ekf it releases the hold onto a receiver's NLOS ramp "
        "still within 5 m, whose speed the filter then carries through the next outage (dam_lock_inertial seed 0 APE "
        "max 3.78 -> 4.77 m; quickstart seed 4 APE p95 5.39 -> 5.77 m), so it is off by default; docs/models.md]",
    )

    hold_allowance: bool = Field(
        False,
        description="a fix refused only by the hold (its own used satellites look direct) is trusted with an allowance "
        "instead: what the held suspects could still move it by (their shift at nlos_bias_m, halved every "
        "hold_half_life_s, RECEIVER_HALF_LIFE_S = 4 s when that is unset), which the host adds to the fix's covariance, "
        "so it weighs in only where the filter is less sure than that (after a blackout on degenerate odometry) and "
        "barely moves a confident one [False: refused for the hold, as before; docs/models.md 'Which test refuses the "
        "good fixes']",
    )

    nlos_bias_m: float = Field(
        50.0,
        ge=0,
        allow_inf_nan=False,
        description="range bias the suspect satellites are weighed with, m (times cos(el) with vertical_reflectors): a fix "
        "is refused only when its suspects "
        "(deficit > gate_sigma) could together move it by more than fault_m, each by its slope (the horizontal shift of "
        "the receiver's least-squares fix per metre of range bias, fusion.monitors.satellite_geometry) times this [50: a "
        "reflection off a surface d away adds at most 2 d to the path (triangle inequality; 2 d cos(el) off a facade "
        "facing the satellite, sim.multipath's image method), and beside a vessel the walls that block a signal and "
        "reflect it stand within about 25 m (a canal's or lock chamber's width, a quay alongside); a direct signal through "
        "a tree crown, 5-10 dB down like a reflection, is thereby not refused when it cannot move the fix by a fault "
        "(charles_river: a 14 deg satellite among 17, slope 0.06 m/m). 0 = every suspect refuses the fix, as before]",
    )
    vertical_reflectors: bool = Field(
        True,
        description="a suspect's range bias is nlos_bias_m times cos(elevation): the surfaces that can reflect a blocked "
        "satellite's signal to a vessel's antenna are vertical (quays, walls, piers, facades, hulls), and off a vertical "
        "surface d away a reflection adds 2 d cos(el) cos(az - az_wall) to the path (the image method, sim.multipath; Hsu "
        "2018, GPS Solutions 22:7, its NLOS delay model 2 d cos(el)); a deck's underside faces away from every satellite "
        "above it, and the water lies below the antenna. A weak satellite near the zenith then cannot move the fix by a "
        "fault [True: library [fast] seeds 0-2, the monitor alone, false alarms charles_river and blinding 0.097 -> 0.073, "
        "gps_jump 0.114 -> 0.083, recall unchanged everywhere (benchmarks/cn0_geometry.py); False: nlos_bias_m at every "
        "elevation, as before]",
    )
    certify_z: float | None = Field(
        None,
        gt=0,
        description="a fix its C/N0 would refuse is trusted, its error bound as the allowance, when the host's prediction "
        "bounds that error below fault_m: |fix - prediction| + certify_z x the prediction's largest sigma [None: refused. "
        "3.7 (chi-square 2 dof at 0.999) cuts the ekf's false alarms by 0.02-0.50 in 11 of 13 library runs at unchanged "
        "recall but raises its APE p95 in 9 of them by up to 0.26 m, the fixes it trusts carrying a reflection's "
        "correlated metre; "
        "docs/models.md 'A fix within a fault of the prediction']",
    )
    fault_m: float = Field(
        5.0,
        gt=0,
        allow_inf_nan=False,
        description="horizontal error the suspects must be able to cause for the fix to be refused, m [5: the fault the "
        "library's integrity scores count (monitor.added_5m)]",
    )
    per_signal: bool = Field(
        True,
        description="expect each constellation's and signal's C/N0 at its own offset from GPS L1 C/A (module docstring) [True; "
        "False: every signal against one template, as before multi-GNSS receivers were read]",
    )
    offsets_db: dict[str, float] = Field(
        default_factory=lambda: dict(PRIOR_OFFSETS_DB),
        description="prior C/N0 offset from GPS L1 C/A per '<system> <signal>', dB, until learned [the difference of the "
        "signals' specified minimum received powers, PRIOR_OFFSETS_DB; a signal not listed: 0]",
    )
    learn_offsets: bool = Field(True, description="learn each signal's offset from the recording once it has enough reports [True]")
    min_samples_per_signal: int = Field(
        40, ge=5, description="reports of a signal buffered before its offset is learned [40: as a template bin's min_samples_per_bin]"
    )
    satellite_levels: bool = Field(
        True,
        description="measure how direct signals differ between satellites from each one's level (module docstring) [True; "
        "False: the bins' sigma alone, as before the spread between satellites was measured]",
    )
    min_samples_per_satellite: int = Field(
        10,
        ge=2,
        description="a satellite's level (the mid_q quantile of its buffered reports about the template) counts once it "
        "holds this many [10: the 0.75 quantile of 10 normal reports scatters by 0.43 of their jitter (sqrt(0.75 * 0.25) / "
        "(phi(0.674) sqrt(10))), below the jitter its levels' spread is compared with; levels_z allows for it]",
    )
    min_satellites: int = Field(
        4,
        ge=3,
        description="satellites with a level needed to measure the spread between satellites [4: what a fix needs; "
        "fewer give no median absolute deviation worth the name]",
    )
    levels_z: float = Field(
        2.0,
        ge=0,
        description="the satellites' levels count as spread between satellites once their spread exceeds the bins' sigma "
        "by this many of its standard errors (MAD_RELATIVE_SE / sqrt(satellites)) [2: a one-sided test at 2.3 %; the "
        "levels of a handful of satellites that share one level scatter by chance]",
    )
    profile_template: tuple[float, float, float] | None = Field(
        None,
        description="a receiver profile: [C/N0 at the horizon (dB-Hz), its rise to the zenith (dB-Hz per unit sin(elevation)), "
        "jitter sigma (dB)] of direct GPS L1 C/A signals, measured for this receiver and antenna under open sky; judges "
        "fixes until the template is learned [None: trust fixes while learning]",
    )

    @model_validator(mode="after")
    def _ordered(self) -> Cn0Params:
        if self.high_q <= self.mid_q:
            raise ValueError(f"high_q {self.high_q} must exceed mid_q {self.mid_q}")
        if self.min_samples_per_bin > self.samples_per_bin:
            raise ValueError(f"min_samples_per_bin {self.min_samples_per_bin} exceeds samples_per_bin {self.samples_per_bin}")
        if self.min_bins > self.bins:
            raise ValueError(f"min_bins {self.min_bins} exceeds bins {self.bins}")
        return self


@lru_cache(maxsize=256)
def per_satellite_gate(gate_sigma: float, n: int) -> float:
    """The level, in sigma, each of a fix's n used satellites is tested at so that a fix whose n signals are all direct
    exceeds it somewhere with the probability one Gaussian jitter exceeds gate_sigma (Sidak 1967): 1 - (1 - p)^n = p_gate.
    Kept per (gate, n): every fix asks it, and a receiver uses a few dozen satellite counts at most."""
    if n <= 1:
        return gate_sigma
    return float(norm.isf(-math.expm1(math.log1p(-float(norm.sf(gate_sigma))) / n)))


def _valid(el_deg: np.ndarray, snr: np.ndarray) -> np.ndarray:
    """Reports usable for the template: finite, elevation in (0, 90] degrees, C/N0 > 0 (0 = not tracked)."""
    return np.isfinite(el_deg) & np.isfinite(snr) & (el_deg > 0) & (el_deg <= 90) & (snr > 0)


class Cn0Template:
    """The direct-signal template learned from one receiver's reports (module docstring): ring buffers per sin(elevation)
    bin, the template line and sigma, each signal's offset and the spread between satellites. It is the receiver's and
    antenna's, not a filter's, so every cn0 monitor judging one receiver's fixes with the same parameters can share one
    (Cn0Templates): it learns each fix once. A monitor learns a fix when it judges the next one, so every sharing monitor
    judges a fix against the template of the fixes before it, as a monitor of its own would."""

    def __init__(self, params: Cn0Params) -> None:
        self.params = params
        p = params
        self._sin = np.full((p.bins, p.samples_per_bin), np.nan)  # ring buffers per sin(el) bin
        self._cn0 = np.full((p.bins, p.samples_per_bin), np.nan)
        self._count = np.zeros(p.bins, dtype=np.int64)  # samples ever added per bin
        self._group = np.full((p.bins, p.samples_per_bin), -1, dtype=np.int64)  # signal index of each sample
        self._sat = np.full((p.bins, p.samples_per_bin), -1, dtype=np.int64)  # satellite index of each sample
        self._satellites: dict[tuple[str, str, int], int] = {}  # (system, signal, number) -> satellite index
        self._between: tuple[float, float] | None = None  # the satellites' levels' spread and the sigma it must exceed (dB)
        self._signals: dict[str, int] = {REFERENCE: 0}  # signal name -> index; offsets by index
        self._offset = np.zeros(1)  # dB from the template, per signal index (priors until learned)
        self._spread = np.full(1, np.nan)  # learned jitter sigma per signal index (dB); the template's for GPS L1 C/A
        self._line: tuple[float, float] | None = None  # template intercept and slope over sin(el), dB-Hz
        self._sigma = math.nan
        self._z_mid, self._z_high = norm.ppf(p.mid_q), norm.ppf(p.high_q)
        self._learned: tuple[float, tuple] | None = None  # (stamp, reports) of the fix learned last through learn_once

    def template(self, el_deg: float | np.ndarray) -> tuple[np.ndarray, float] | None:
        """Direct GPS L1 C/A C/N0 (dB-Hz) at these elevations and its jitter sigma (dB): learned, else the receiver profile's,
        else None (learning)."""
        if self._line is not None:
            (a, b), sigma = self._line, self._sigma
        elif self.params.profile_template is not None:
            a, b, sigma = self.params.profile_template
        else:
            return None
        return a + b * np.sin(np.deg2rad(np.asarray(el_deg, dtype=float))), sigma

    @property
    def between_satellites(self) -> tuple[float, float] | None:
        """At the last fit: the spread of the satellites' levels and what it had to exceed to widen sigma (dB), or None (not
        measured: too few satellites with a level, or satellite_levels off)."""
        return self._between

    def offsets(self) -> dict[str, float]:
        """Each signal's current offset from the template (dB), learned or prior."""
        return {name: float(self._offset[k]) for name, k in self._signals.items()}

    def signal(self, sat) -> int:
        """The index of a satellite's signal (registered on first sight with its prior offset); 0 without per_signal."""
        if not self.params.per_signal:
            return 0
        name = f"{getattr(sat, 'system', 'GPS')} {getattr(sat, 'signal', 'L1 C/A')}"
        if name not in self._signals:
            self._signals[name] = len(self._signals)
            self._offset = np.append(self._offset, self.params.offsets_db.get(name, 0.0))
            self._spread = np.append(self._spread, np.nan)
        return self._signals[name]

    def _satellite(self, sat) -> int:
        """The index of a satellite (system, signal and number), registered on first sight."""
        key = (str(getattr(sat, "system", "GPS")), str(getattr(sat, "signal", "L1 C/A")), int(sat.prn))
        return self._satellites.setdefault(key, len(self._satellites))

    def counting_bins(self) -> int:
        """How many bins hold min_samples_per_bin samples (the template needs min_bins)."""
        return int((self._count >= self.params.min_samples_per_bin).sum())

    def signal_scales(self, signals: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Each signal's offset from the template (dB) and its learned jitter sigma (dB, NaN until learned)."""
        return self._offset[signals], self._spread[signals]

    def learn(self, obs: FixObservation) -> None:
        """Learn from every tracked satellite of a fix (used or not) and refit the template, without judging it."""
        if not obs.sats:
            return
        el = np.array([_float(s.el_deg) for s in obs.sats])
        snr = np.array([_float(s.snr) for s in obs.sats])
        ok = _valid(el, snr)
        if not ok.any():
            return
        s = np.sin(np.deg2rad(el[ok]))
        b = np.minimum((s * self.params.bins).astype(int), self.params.bins - 1)
        signals = [self.signal(sat) for sat, k in zip(obs.sats, ok) if k]
        satellites = [self._satellite(sat) for sat, k in zip(obs.sats, ok) if k]
        for k, (sk, ck) in enumerate(zip(s, snr[ok])):
            slot = self._count[b[k]] % self.params.samples_per_bin
            self._sin[b[k], slot], self._cn0[b[k], slot], self._group[b[k], slot] = sk, ck, signals[k]
            self._sat[b[k], slot] = satellites[k]
            self._count[b[k]] += 1
        self._fit()

    def learn_once(self, obs: FixObservation) -> None:
        """learn(obs) unless this fix (its stamp and reports) was the last one learned: another monitor sharing the
        template learned it."""
        key = (obs.stamp, obs.sats)
        if self._learned is not None and self._learned == key:
            return
        self._learned = key
        self.learn(obs)

    def _fit(self) -> None:
        """Refit the template line and sigma from the buffers (see the module docstring)."""
        p = self.params
        full = self._count >= p.min_samples_per_bin
        if full.sum() < p.min_bins:
            return
        sin_b, cn0_b = self._sin[full], self._cn0[full]
        several = len(self._signals) > 1
        if several:  # each signal's reports brought to GPS L1 C/A's level (a GPS L1 C/A-only receiver never gets here)
            cn0_b = cn0_b - np.where(self._group[full] >= 0, self._offset[np.maximum(self._group[full], 0)], 0.0)
        weight = np.minimum(self._count[full], p.samples_per_bin).astype(float)
        centre = np.nanmean(sin_b, axis=1)
        a, b = 0.0, 0.0
        for _ in range(p.iterations):
            residual = cn0_b - (a + b * sin_b)
            q_mid, q_high = _row_quantiles(residual, (p.mid_q, p.high_q))
            sigma = max(float(np.median((q_high - q_mid) / (self._z_high - self._z_mid))), p.min_sigma_db)
            direct = a + b * centre + q_mid - self._z_mid * sigma
            if np.ptp(centre) <= 1e-6:  # all populated bins at one elevation: a level, no slope
                a, b = float(np.average(direct, weights=weight)), 0.0
            else:
                b, a = np.polyfit(centre, direct, 1, w=np.sqrt(weight))
                a, b = float(a), float(b)
        self._line, self._sigma = (a, b), sigma
        if several and p.learn_offsets:
            self._fit_offsets()
        if p.satellite_levels:
            self._sigma = self._between_satellites(self._sigma)

    def _between_satellites(self, sigma: float) -> float:
        """The template's sigma given how direct signals differ between satellites (module docstring): the bins' `sigma`,
        or, when the satellites' levels spread more than it, the robust spread of all reports, satellites weighted equally."""
        assert self._line is not None
        p, (a, b) = self.params, self._line
        self._between = None
        stored = self._sat >= 0
        sat = self._sat[stored]
        residual = self._cn0[stored] - (a + b * self._sin[stored])
        if len(self._signals) > 1:
            residual = residual - self._offset[self._group[stored]]
        counts = np.bincount(sat, minlength=len(self._satellites))
        ready = counts >= p.min_samples_per_satellite
        if ready.sum() < p.min_satellites:
            return sigma
        levels = _quantile_by_group(residual, sat, counts, p.mid_q)[ready]
        spread = MAD_TO_SIGMA * float(np.median(np.abs(levels - np.median(levels))))
        self._between = (spread, sigma * (1.0 + p.levels_z * MAD_RELATIVE_SE / math.sqrt(len(levels))))
        if spread <= self._between[1]:
            return sigma
        counted = ready[sat]
        residual, weight = residual[counted], 1.0 / counts[sat[counted]]
        centre = _weighted_median(residual, weight)
        return max(sigma, MAD_TO_SIGMA * _weighted_median(np.abs(residual - centre), weight))

    def _fit_offsets(self) -> None:
        """Each signal's offset from its reports about the template (module docstring), relative to an anchor signal."""
        assert self._line is not None
        p, (a, b) = self.params, self._line
        stored = self._group >= 0
        groups, sin, cn0 = self._group[stored], self._sin[stored], self._cn0[stored]
        counts = np.bincount(groups, minlength=len(self._signals))
        ready = counts >= p.min_samples_per_signal
        if not ready.any():
            return
        residual = cn0 - (a + b * sin)
        level = np.full(len(self._signals), np.nan)
        for k in np.flatnonzero(ready):
            q_mid, q_high = _sorted_quantiles(np.sort(residual[groups == k]), np.array([p.mid_q, p.high_q]))
            level[k] = float(q_mid) - self._z_mid * self._sigma
            if k:
                self._spread[k] = max(float(q_high - q_mid) / (self._z_high - self._z_mid), self._sigma)
        anchor = 0 if ready[0] else int(np.argmax(counts))
        self._offset[ready] = self._offset[anchor] + level[ready] - level[anchor]


class Cn0Monitor(Monitor):
    """Distrusts a fix that uses a satellite whose C/N0 falls gate_sigma below the learned template; statistic is the largest normalised deficit."""

    name = "cn0"

    def __init__(self, params: Cn0Params, learned: Cn0Template | None = None) -> None:
        self.params = params
        self.gate = params.gate_sigma
        self.learned = learned if learned is not None else Cn0Template(params)
        """The template it judges against (its own, or one shared with the monitors judging the same receiver)."""
        self._pending: FixObservation | None = None  # the fix committed last, learned before the next is judged
        self._recent: deque[tuple[float, float, float]] = deque()  # (stamp, deficit, suspects' shift) of committed fixes within hold_s
        self._judged: tuple[FixObservation, tuple[float, float | None, str, str, float]] | None = None  # check's, for commit

    def _catch_up(self) -> None:
        """Learn the fix committed last (once per sharing template), so that the template holds every fix before this one."""
        if self._pending is not None:
            self.learned.learn_once(self._pending)
            self._pending = None

    def template(self, el_deg: float | np.ndarray) -> tuple[np.ndarray, float] | None:
        """The learned template's (Cn0Template.template), with every committed fix learned."""
        self._catch_up()
        return self.learned.template(el_deg)

    @property
    def between_satellites(self) -> tuple[float, float] | None:
        """The learned template's (Cn0Template.between_satellites), with every committed fix learned."""
        self._catch_up()
        return self.learned.between_satellites

    def offsets(self) -> dict[str, float]:
        """The learned template's (Cn0Template.offsets), with every committed fix learned."""
        self._catch_up()
        return self.learned.offsets()

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        self._judged = (obs, self._deficit(obs))  # satellite_deficits first learns the fix committed last
        deficit, sigma, named, note, _ = self._judged[1]
        if sigma is None:
            return Verdict(True, math.nan, note)
        recent = [(d, shift, obs.stamp - t) for t, d, shift in self._recent if obs.stamp - self.params.hold_s <= t < obs.stamp]
        held = [(d, shift, age) for d, shift, age in recent if self._still_carried(shift, age)]
        statistic = max([deficit, *(d for d, _, _ in held)])
        bound = self._certified(obs, ctx) if statistic > self.gate else None
        if bound is not None:
            why = (
                f"C/N0 {statistic:.1f} sigma low now or within {self.params.hold_s:g} s, but the host's prediction puts the fix within {bound:.1f} m"
            )
            return Verdict(True, statistic, why + note, rule="cn0.certified", allowance_m=bound)
        if deficit > self.gate:
            return Verdict(
                False, statistic, f"C/N0 deficit > {self.gate:g} sigma ({sigma:.1f} dB): {named}" + note, on_its_own=True, rule="cn0.deficit"
            )
        if statistic > self.gate:
            allowance = max(self._carried(shift, age) for d, shift, age in held if d > self.gate)
            if self.params.hold_allowance and math.isfinite(allowance):
                why = f"a used satellite's C/N0 was {statistic:.1f} sigma low within {self.params.hold_s:g} s: trusted, allowing {allowance:.1f} m"
                return Verdict(True, statistic, why + note, rule="cn0.hold", allowance_m=allowance)
            return Verdict(
                False,
                statistic,
                f"a used satellite's C/N0 was {statistic:.1f} sigma low within {self.params.hold_s:g} s "
                "(the receiver's filter still carries it)" + note,
                on_its_own=True,
                rule="cn0.hold",
            )
        return Verdict(True, statistic, "C/N0 consistent with a direct signal" + note)

    def _certified(self, obs: FixObservation, ctx: FixContext | None) -> float | None:
        """The fix's error bound by the host's prediction (distance to it plus certify_z of its largest sigma), m, when
        that is below fault_m; else None."""
        z = self.params.certify_z
        if z is None or ctx is None or ctx.predicted is None:
            return None
        mean, cov, _ = ctx.predicted
        if not (np.all(np.isfinite(cov)) and np.all(np.isfinite(mean))):
            return None
        bound = float(np.linalg.norm(obs.xy - mean) + z * math.sqrt(max(float(np.linalg.eigvalsh(cov)[-1]), 0.0)))
        return bound if bound < self.params.fault_m else None

    def _carried(self, shift: float, age_s: float) -> float:
        """How far a held fault (its suspects could move the fix `shift` m) may still move the receiver's output `age_s`
        later, m: halved every hold_half_life_s (RECEIVER_HALF_LIFE_S when unset)."""
        return shift * 0.5 ** (age_s / (self.params.hold_half_life_s or RECEIVER_HALF_LIFE_S))

    def _still_carried(self, shift: float, age_s: float) -> bool:
        """Whether a held fault (its suspects could move the fix `shift` m) may still move the receiver's output by more
        than fault_m `age_s` later: its effect halves every hold_half_life_s (always, without a half-life)."""
        return self.params.hold_half_life_s is None or self._carried(shift, age_s) > self.params.fault_m

    def _deficit(self, obs: FixObservation) -> tuple[float, float | None, str, str, float]:
        """(largest normalised deficit of the used satellites that count, template sigma or None when it cannot judge,
        the satellites over the gate, a note on skipped reports, suspects weighed and found harmless, or why it cannot
        judge, how far the suspects could move the fix (inf when not weighed)). The suspects (deficit over the gate)
        count only when they could together move the fix by more than fault_m (see nlos_bias_m); otherwise the deficit
        is the largest of the others'."""
        judged = self.satellite_deficits(obs)
        if isinstance(judged, str):
            return math.nan, None, "", judged, math.inf
        raw, used, sigma, skipped = judged
        names = [_label(s) for s in used]
        level = per_satellite_gate(self.gate, len(raw)) if self.params.family_gate else self.gate
        deficit = raw * (self.gate / level)  # in units of the fix's gate: over self.gate is over the satellites' level
        suspect = deficit > self.gate
        named = ", ".join(f"{name} {d:.1f}" for d, name in sorted(zip(raw.tolist(), names), reverse=True) if d > level)
        if named and level != self.gate:
            named += f" (over {level:.2f} sigma, the gate of each of {len(raw)} satellites)"
        shift = self._suspects_shift(obs, [s for s, k in zip(used, suspect) if k])
        if shift is None:
            return float(deficit.max()), sigma, named, skipped, math.inf
        if shift > self.params.fault_m:
            return float(deficit.max()), sigma, f"{named} (together they can move the fix {shift:.1f} m)", skipped, shift
        harmless = f"; {named} below the template, but together they move the fix at most {shift:.1f} m (<= fault_m {self.params.fault_m:g})"
        return float(deficit[~suspect].max()) if (~suspect).any() else 0.0, sigma, "", skipped + harmless, shift

    def _suspects_shift(self, obs: FixObservation, suspects: list) -> float | None:
        """How far the suspect satellites could move the fix together (nlos_bias_m times the sum of their slopes), m, or
        None when they are not weighed (none, or nlos_bias_m 0)."""
        if not suspects or self.params.nlos_bias_m <= 0:
            return None
        used = [s for s in obs.sats if getattr(s, "used", False)]
        slopes = horizontal_slopes(
            np.array([_float(s.el_deg) for s in used]), np.array([_float(s.az_deg) for s in used]), [str(getattr(s, "system", "GPS")) for s in used]
        )
        picked = [k for k, s in enumerate(used) if any(s is t for t in suspects)]
        bias = np.full(len(picked), self.params.nlos_bias_m)
        if self.params.vertical_reflectors:
            bias *= np.cos(np.deg2rad([_float(used[k].el_deg) for k in picked]))
        return float(bias @ slopes[picked])

    def satellite_deficits(self, obs: FixObservation) -> tuple[np.ndarray, list, float, str] | str:
        """Each used satellite's normalised C/N0 deficit below what a direct signal gives (the verdict's evidence, per
        satellite): (deficits, the used satellites' reports they belong to, the template's sigma in dB, a note on
        skipped reports), or why the fix cannot be judged."""
        self._catch_up()
        t = self.learned
        used = [s for s in obs.sats if getattr(s, "used", False)]
        if not used:
            return "unchecked: no used satellite reported"
        el = np.array([_float(s.el_deg) for s in used])
        snr = np.array([_float(s.snr) for s in used])
        ok = _valid(el, snr)
        skipped = "" if ok.all() else f"; skipped PRN {', '.join(str(s.prn) for s, k in zip(used, ok) if not k)} (bad C/N0 or elevation)"
        if not ok.any():
            return "unchecked: no used satellite with a valid C/N0 and elevation" + skipped
        learned = t.template(el[ok])
        if learned is None:
            return f"learning the C/N0 template ({t.counting_bins()}/{self.params.min_bins} bins)" + skipped
        expected, sigma = learned
        judged = [s for s, k in zip(used, ok) if k]
        signals = [t.signal(s) for s in judged]
        scale: float | np.ndarray = sigma
        if any(signals):
            offset, own = t.signal_scales(signals)
            expected = expected + offset
            scale = np.where(np.isfinite(own), np.maximum(own, sigma), sigma)
        return (expected - snr[ok]) / scale, judged, sigma, skipped

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        """Remember the fix's deficit for the hold; its tracked satellites (used or not) are learned before the next fix is judged."""
        deficit, _, _, _, shift = self._judged[1] if self._judged is not None and self._judged[0] is obs else self._deficit(obs)
        self._judged = None
        while self._recent and self._recent[0][0] < obs.stamp - self.params.hold_s:
            self._recent.popleft()
        if math.isfinite(deficit) and self.params.hold_s > 0:
            self._recent.append((obs.stamp, deficit, shift))
        self._pending = obs

    def calibrate(self, obs: FixObservation) -> None:
        """Learn from every tracked satellite of a fix (used or not) and refit the template, without judging it."""
        self._catch_up()
        self.learned.learn(obs)


class Cn0Templates:
    """The templates learned from one receiver's fixes, one per set of cn0 parameters: every cn0 monitor built with the
    same registry and parameters (a run's estimators judging one receiver) shares one, learning each fix once. The
    monitors sharing one must judge the same fixes: hosts that screen the receiver's output differently (one takes its
    dead-reckoned fixes, one does not) take their templates from different streams (stream)."""

    def __init__(self) -> None:
        self._by_params: dict[str, Cn0Template] = {}
        self._streams: dict[Hashable, Cn0Templates] = {}

    def get(self, params: Cn0Params) -> Cn0Template:
        """The template these parameters learn, made on first use."""
        return self._by_params.setdefault(params.model_dump_json(), Cn0Template(params))

    def stream(self, screening: Hashable) -> Cn0Templates:
        """The templates of the monitors whose hosts pass the receiver's fixes through this screening."""
        return self._streams.setdefault(screening, Cn0Templates())


def _quantile_by_group(values: np.ndarray, group: np.ndarray, counts: np.ndarray, q: float) -> np.ndarray:
    """The q quantile (linear interpolation, as numpy.quantile) of `values` within each group 0..len(counts)-1 (`counts`:
    the group sizes, np.bincount(group)); NaN for an empty group."""
    by_value = np.argsort(values)  # then a stable (radix) sort by group: np.lexsort((values, group))'s values, 6x faster
    ordered = values[by_value][np.argsort(group[by_value].astype(np.uint16), kind="stable")]
    start = np.cumsum(counts) - counts
    position = start + np.maximum(counts - 1, 0) * q
    low = np.minimum(np.floor(position).astype(np.int64), len(ordered) - 1)
    high = np.minimum(low + 1, np.maximum(start + counts - 1, 0))
    out = ordered[low] + (position - low) * (ordered[high] - ordered[low])
    return np.where(counts > 0, out, np.nan)


def _row_quantiles(values: np.ndarray, q: tuple[float, ...]) -> np.ndarray:
    """np.nanquantile(values, q, axis=1) of a 2-D array, bit for bit, without its per-row Python loop: the rows that hold
    the same number of values (the NaNs sorted last) are taken at once; (len(q), rows), NaN for a row of NaNs."""
    out = np.full((len(q), len(values)), np.nan)
    held = np.count_nonzero(~np.isnan(values), axis=1)
    ordered = np.sort(values, axis=1)
    for count in np.unique(held[held > 0]):
        rows = np.flatnonzero(held == count)
        out[:, rows] = _sorted_quantiles(ordered[rows, :count].T, np.asarray(q))
    return out


def _sorted_quantiles(ordered: np.ndarray, q: np.ndarray) -> np.ndarray:
    """np.quantile(ordered, q, axis=0) (method 'linear') of columns already sorted along axis 0, bit for bit: its virtual
    indices, neighbours and interpolation (numpy.lib._function_base_impl._lerp), without sorting the columns again."""
    n = len(ordered)
    virtual = (n - 1) * q
    previous = np.floor(virtual)
    above = virtual >= n - 1
    previous[above] = n - 1
    following = np.where(above, n - 1, previous + 1).astype(np.int64)
    gamma = (virtual - np.where(above, -1.0, previous)).reshape(-1, *([1] * (ordered.ndim - 1)))
    low, high = ordered[previous.astype(np.int64)], ordered[following]
    step = high - low
    out = low + step * gamma
    np.subtract(high, step * (1 - gamma), out=out, where=gamma >= 0.5)
    return out


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The smallest value at which the cumulative weight reaches half the total (the weighted lower median)."""
    order = np.argsort(values, kind="stable")
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])


def _label(sat) -> str:
    """How a reason names a satellite: 'PRN n' for GPS L1 C/A, else its system, number and signal."""
    system, signal = getattr(sat, "system", "GPS"), getattr(sat, "signal", "L1 C/A")
    return f"PRN {sat.prn}" if f"{system} {signal}" == REFERENCE else f"{system} {sat.prn} {signal}"


def _float(value) -> float:
    """A report field as float, NaN when it is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
