"""Wave-induced roll, pitch and heave of a small catamaran: a sum of sinusoids drawn from a wave spectrum, either a
fully developed Pierson-Moskowitz sea whose significant wave height follows the Douglas sea state, or the fetch-limited
wind sea that a given wind raises over a given fetch (WindWaves: a river basin's chop)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.integrate import quad

GRAVITY = 9.81
# Douglas sea-state code -> significant wave height (m), the middle of each band; 0 is glassy calm.
SIGNIFICANT_WAVE_HEIGHT_M = (0.0, 0.05, 0.3, 0.875, 1.875)
JONSWAP_GAMMA = 3.3
"""Peak enhancement of the JONSWAP spectrum, its mean over the fetch-limited seas measured in the North Sea (Hasselmann
et al. 1973, Dtsch. Hydrogr. Z. Reihe A 8(12))."""
JONSWAP_SIGMA = (0.07, 0.09)
"""Width of the JONSWAP peak below and above the peak frequency (Hasselmann et al. 1973)."""


class WindWaves(BaseModel):
    """A fetch-limited wind sea: the significant height and peak period a steady wind raises over a straight fetch, by
    the Coastal Engineering Manual's deep-water growth laws (EM 1110-2-1100 Part II, ch. 2, eqs. II-2-36 and II-2-37,
    in the friction velocity u* = U10 sqrt(C_D), C_D = 0.001 (1.1 + 0.035 U10)), capped at the fully developed sea; its
    spectrum is JONSWAP's. A sheltered river basin's chop: short, steep waves that a hull of a few metres filters but
    that still roll and pitch it by a degree or so."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    wind_mps: float = Field(
        gt=0.0,
        le=30.0,
        description="wind speed 10 m above the water (U10), m/s [Boston's annual mean is about 5.5 m/s (12.3 mph at Logan "
        "airport, NOAA Comparative Climatic Data)]",
    )
    fetch_m: float = Field(
        gt=0.0,
        le=1.0e6,
        description="straight-line distance over water the wind blows along to the vessel, m (the CEM's fetch: its width is "
        "not used) [the Charles River Basin is 3,000 m in a straight line from the Boston University Bridge to the "
        "Longfellow Bridge (charles_river's route, stations 127 and 3,201 m), bearing 16 deg north of east: the fetch of a "
        "west-south-westerly, Boston's prevailing summer wind being south-westerly]",
    )

    @property
    def friction_velocity_mps(self) -> float:
        """u* = U10 sqrt(C_D), C_D = 0.001 (1.1 + 0.035 U10) (CEM eq. II-2-36's drag coefficient), m/s."""
        return self.wind_mps * math.sqrt(0.001 * (1.1 + 0.035 * self.wind_mps))

    @property
    def significant_height_m(self) -> float:
        """Hm0 = 4.13e-2 (u*^2 / g) (g X / u*^2)^(1/2), at most the fully developed 211.5 u*^2 / g (CEM II-2-36, II-2-37), m."""
        u2 = self.friction_velocity_mps**2
        return min(4.13e-2 * math.sqrt(GRAVITY * self.fetch_m / u2), 211.5) * u2 / GRAVITY

    @property
    def peak_period_s(self) -> float:
        """Tp = 0.651 (u* / g) (g X / u*^2)^(1/3), at most the fully developed 239.8 u* / g (CEM II-2-36, II-2-37), s."""
        u = self.friction_velocity_mps
        return min(0.651 * (GRAVITY * self.fetch_m / u**2) ** (1.0 / 3.0), 239.8) * u / GRAVITY


@dataclass(frozen=True)
class WaveMotion:
    """Vessel response to waves: per component frequency (rad/s), phase, and amplitudes of heave
    (m), roll and pitch (rad). Evaluate with `at(ts)`; zero amplitude when the sea is calm."""

    omega: np.ndarray
    phase: np.ndarray
    heave_amp: np.ndarray
    roll_amp: np.ndarray
    pitch_amp: np.ndarray

    @classmethod
    def from_sea_state(
        cls,
        sea_state: int,
        rng: np.random.Generator,
        n_components: int = 24,
        beam_m: float = 2.4,
        length_m: float = 4.9,
    ) -> WaveMotion:
        """Draw components for a Douglas sea state (0-4, the range an ASV survey runs in).

        A catamaran of the given beam and length filters waves shorter than itself: each
        component's slope is scaled by sinc(k * L / 2) along the hull and across the beam, so
        short chop moves the boat less than long swell of the same slope.
        """
        if not 0 <= sea_state < len(SIGNIFICANT_WAVE_HEIGHT_M):
            raise ValueError(f"sea_state must be 0..{len(SIGNIFICANT_WAVE_HEIGHT_M) - 1}, got {sea_state}")
        hs = SIGNIFICANT_WAVE_HEIGHT_M[sea_state]
        # Peak frequency of a fully developed PM sea with this Hs: omega_p = 0.4 sqrt(g / Hs).
        omega_p = 0.4 * np.sqrt(GRAVITY / hs) if hs > 0 else 1.0
        omega = np.linspace(0.6 * omega_p, 3.0 * omega_p, n_components)
        return cls._hull_response(omega, _pierson_moskowitz(omega, hs, omega_p), rng, beam_m, length_m)

    @classmethod
    def from_wind(cls, sea: WindWaves, rng: np.random.Generator, n_components: int = 24, beam_m: float = 2.4, length_m: float = 4.9) -> WaveMotion:
        """Draw components for a fetch-limited wind sea (its JONSWAP spectrum over 0.6-3 times the peak frequency, as
        from_sea_state's), filtered by the hull as there."""
        omega_p = 2.0 * np.pi / sea.peak_period_s
        omega = np.linspace(0.6 * omega_p, 3.0 * omega_p, n_components)
        return cls._hull_response(omega, jonswap(omega, sea.significant_height_m, omega_p), rng, beam_m, length_m)

    @classmethod
    def _hull_response(cls, omega: np.ndarray, spectrum: np.ndarray, rng: np.random.Generator, beam_m: float, length_m: float) -> WaveMotion:
        """Components of a spectrum S(omega) (m^2 s) on the evenly spaced frequencies omega, each with a random encounter
        angle and phase, their slopes filtered by the hull's length and beam."""
        n_components = len(omega)
        d_omega = omega[1] - omega[0]
        amp = np.sqrt(2.0 * spectrum * d_omega)
        k = omega**2 / GRAVITY
        encounter = rng.uniform(0.0, 2.0 * np.pi, n_components)
        phase = rng.uniform(0.0, 2.0 * np.pi, n_components)
        slope = k * amp
        return cls(
            omega=omega,
            phase=phase,
            heave_amp=amp * np.abs(np.sinc(k * length_m / (2 * np.pi))) * np.abs(np.sinc(k * beam_m / (2 * np.pi))),
            roll_amp=slope * np.sin(encounter) * np.abs(np.sinc(k * beam_m / (2 * np.pi))),
            pitch_amp=slope * np.cos(encounter) * np.abs(np.sinc(k * length_m / (2 * np.pi))),
        )

    def at(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Heave (m), roll and pitch (rad) at times ts (any shape)."""
        ts = np.asarray(ts, dtype=float)
        arg = np.multiply.outer(ts, self.omega) + self.phase
        s = np.sin(arg)
        return s @ self.heave_amp, s @ self.roll_amp, np.cos(arg) @ self.pitch_amp


def jonswap(omega: np.ndarray, hs: float, omega_p: float) -> np.ndarray:
    """JONSWAP spectral density S(omega) in m^2 s (gamma JONSWAP_GAMMA), scaled so that 4 sqrt(m0) over all frequencies
    is the significant wave height hs."""
    if hs == 0:
        return np.zeros_like(omega)
    total = quad(lambda w: float(_jonswap_shape(np.array([w]), omega_p)[0]), 0.2 * omega_p, 20.0 * omega_p, limit=200)[0]
    return (hs / 4.0) ** 2 / total * _jonswap_shape(np.asarray(omega, dtype=float), omega_p)


def _jonswap_shape(omega: np.ndarray, omega_p: float) -> np.ndarray:
    """The JONSWAP spectrum's shape, omega^-5 exp(-5/4 (omega_p / omega)^4) gamma^r, unscaled."""
    sigma = np.where(omega <= omega_p, JONSWAP_SIGMA[0], JONSWAP_SIGMA[1])
    r = np.exp(-((omega - omega_p) ** 2) / (2.0 * sigma**2 * omega_p**2))
    return omega**-5.0 * np.exp(-1.25 * (omega_p / omega) ** 4) * JONSWAP_GAMMA**r


def _pierson_moskowitz(omega: np.ndarray, hs: float, omega_p: float) -> np.ndarray:
    """PM spectral density S(omega) in m^2 s for significant wave height hs and peak omega_p."""
    if hs == 0:
        return np.zeros_like(omega)
    return (5.0 / 16.0) * hs**2 * omega_p**4 / omega**5 * np.exp(-1.25 * (omega_p / omega) ** 4)
