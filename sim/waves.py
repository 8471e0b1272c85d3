"""Wave-induced roll, pitch and heave of a small catamaran: a sum of sinusoids drawn from a
Pierson-Moskowitz spectrum whose significant wave height follows the sea state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GRAVITY = 9.81
# Douglas sea-state code -> significant wave height (m), the middle of each band; 0 is glassy calm.
SIGNIFICANT_WAVE_HEIGHT_M = (0.0, 0.05, 0.3, 0.875, 1.875)


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
        d_omega = omega[1] - omega[0]
        spectrum = _pierson_moskowitz(omega, hs, omega_p)
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


def _pierson_moskowitz(omega: np.ndarray, hs: float, omega_p: float) -> np.ndarray:
    """PM spectral density S(omega) in m^2 s for significant wave height hs and peak omega_p."""
    if hs == 0:
        return np.zeros_like(omega)
    return (5.0 / 16.0) * hs**2 * omega_p**4 / omega**5 * np.exp(-1.25 * (omega_p / omega) ** 4)
