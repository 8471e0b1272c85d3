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
with d > gate_sigma look NLOS; a fix's deficit is the largest d among its used satellites. The
receiver's navigation filter smooths its raw solutions, so an NLOS epoch's error lingers in the
fixes that follow for a few seconds after the reflected satellite is dropped (on charles_river 62
of the 63 fixes that the environment put > 5 m off without a used NLOS satellite were within 5.2 s
of one). The statistic is therefore the largest deficit over the last `hold_s` seconds, and the fix
is distrusted when it exceeds gate_sigma. Until `min_bins` bins hold `min_samples_per_bin`
samples the monitor cannot judge and trusts the fix (reason says it is learning). Satellites with
a non-finite or non-positive C/N0 or elevation are skipped and named in the reason.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.stats import norm

from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.verdict import Verdict


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
        "a typical 8 dB reflection loss]",
    )
    hold_s: float = Field(
        6.0,
        ge=0,
        description="a deficit is held this long, s [6: a consumer receiver's filter halves a raw fault's effect on its "
        "output in about 4 s; 0 = no hold]",
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


def _valid(el_deg: np.ndarray, snr: np.ndarray) -> np.ndarray:
    """Reports usable for the template: finite, elevation in (0, 90] degrees, C/N0 > 0 (0 = not tracked)."""
    return np.isfinite(el_deg) & np.isfinite(snr) & (el_deg > 0) & (el_deg <= 90) & (snr > 0)


class Cn0Monitor(Monitor):
    """Distrusts a fix that uses a satellite whose C/N0 falls gate_sigma below the learned template; statistic is the largest normalised deficit."""

    name = "cn0"

    def __init__(self, params: Cn0Params) -> None:
        self.params = params
        self.gate = params.gate_sigma
        p = params
        self._sin = np.full((p.bins, p.samples_per_bin), np.nan)  # ring buffers per sin(el) bin
        self._cn0 = np.full((p.bins, p.samples_per_bin), np.nan)
        self._count = np.zeros(p.bins, dtype=np.int64)  # samples ever added per bin
        self._line: tuple[float, float] | None = None  # template intercept and slope over sin(el), dB-Hz
        self._sigma = math.nan
        self._z_mid, self._z_high = norm.ppf(p.mid_q), norm.ppf(p.high_q)
        self._recent: deque[tuple[float, float]] = deque()  # (stamp, deficit) of committed fixes within hold_s

    def template(self, el_deg: float | np.ndarray) -> tuple[np.ndarray, float] | None:
        """Learned direct-signal C/N0 (dB-Hz) at these elevations and its jitter sigma (dB), or None while learning."""
        if self._line is None:
            return None
        a, b = self._line
        return a + b * np.sin(np.deg2rad(np.asarray(el_deg, dtype=float))), self._sigma

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        deficit, sigma, named, note = self._deficit(obs)
        if sigma is None:
            return Verdict(True, math.nan, note)
        held = [d for t, d in self._recent if obs.stamp - self.params.hold_s <= t < obs.stamp]
        statistic = max([deficit, *held])
        if deficit > self.gate:
            return Verdict(False, statistic, f"C/N0 deficit > {self.gate:g} sigma ({sigma:.1f} dB): {named}" + note, on_its_own=True)
        if statistic > self.gate:
            return Verdict(
                False,
                statistic,
                f"a used satellite's C/N0 was {statistic:.1f} sigma low within {self.params.hold_s:g} s "
                "(the receiver's filter still carries it)" + note,
                on_its_own=True,
            )
        return Verdict(True, statistic, "C/N0 consistent with a direct signal" + note)

    def _deficit(self, obs: FixObservation) -> tuple[float, float | None, str, str]:
        """(largest normalised deficit of the used satellites, template sigma or None when it cannot judge,
        the satellites over the gate, a note on skipped reports or why it cannot judge)."""
        used = [s for s in obs.sats if getattr(s, "used", False)]
        if not used:
            return math.nan, None, "", "unchecked: no used satellite reported"
        el = np.array([_float(s.el_deg) for s in used])
        snr = np.array([_float(s.snr) for s in used])
        ok = _valid(el, snr)
        skipped = "" if ok.all() else f"; skipped PRN {', '.join(str(s.prn) for s, k in zip(used, ok) if not k)} (bad C/N0 or elevation)"
        if not ok.any():
            return math.nan, None, "", "unchecked: no used satellite with a valid C/N0 and elevation" + skipped
        learned = self.template(el[ok])
        if learned is None:
            full = int((self._count >= self.params.min_samples_per_bin).sum())
            return math.nan, None, "", f"learning the C/N0 template ({full}/{self.params.min_bins} bins)" + skipped
        expected, sigma = learned
        deficit = (expected - snr[ok]) / sigma
        prns = [s.prn for s, k in zip(used, ok) if k]
        named = ", ".join(f"PRN {prn} {d:.1f}" for d, prn in sorted(zip(deficit.tolist(), prns), reverse=True) if d > self.gate)
        return float(deficit.max()), sigma, named, skipped

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        """Remember the fix's deficit for the hold; learn from every tracked satellite (used or not) and refit the template."""
        deficit = self._deficit(obs)[0]
        while self._recent and self._recent[0][0] < obs.stamp - self.params.hold_s:
            self._recent.popleft()
        if math.isfinite(deficit) and self.params.hold_s > 0:
            self._recent.append((obs.stamp, deficit))
        if not obs.sats:
            return
        el = np.array([_float(s.el_deg) for s in obs.sats])
        snr = np.array([_float(s.snr) for s in obs.sats])
        ok = _valid(el, snr)
        if not ok.any():
            return
        s = np.sin(np.deg2rad(el[ok]))
        b = np.minimum((s * self.params.bins).astype(int), self.params.bins - 1)
        for k, (sk, ck) in enumerate(zip(s, snr[ok])):
            slot = self._count[b[k]] % self.params.samples_per_bin
            self._sin[b[k], slot], self._cn0[b[k], slot] = sk, ck
            self._count[b[k]] += 1
        self._fit()

    def _fit(self) -> None:
        """Refit the template line and sigma from the buffers (see the module docstring)."""
        p = self.params
        full = self._count >= p.min_samples_per_bin
        if full.sum() < p.min_bins:
            return
        sin_b, cn0_b = self._sin[full], self._cn0[full]
        weight = np.minimum(self._count[full], p.samples_per_bin).astype(float)
        centre = np.nanmean(sin_b, axis=1)
        a, b = 0.0, 0.0
        for _ in range(p.iterations):
            residual = cn0_b - (a + b * sin_b)
            q_mid, q_high = np.nanquantile(residual, [p.mid_q, p.high_q], axis=1)
            sigma = max(float(np.median((q_high - q_mid) / (self._z_high - self._z_mid))), p.min_sigma_db)
            direct = a + b * centre + q_mid - self._z_mid * sigma
            if np.ptp(centre) <= 1e-6:  # all populated bins at one elevation: a level, no slope
                a, b = float(np.average(direct, weights=weight)), 0.0
            else:
                b, a = np.polyfit(centre, direct, 1, w=np.sqrt(weight))
                a, b = float(a), float(b)
        self._line, self._sigma = (a, b), sigma


def _float(value) -> float:
    """A report field as float, NaN when it is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
