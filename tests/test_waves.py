"""Wave spectra and the fetch-limited wind sea: the growth laws' scaling, an independent formula, the spectrum's energy and
peak, determinism."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from scipy.integrate import quad

from sim.waves import GRAVITY, WaveMotion, WindWaves, jonswap


def test_the_basin_at_bostons_mean_wind_gives_a_decimetre_chop_of_about_a_second():
    sea = WindWaves(wind_mps=5.5, fetch_m=3000.0)
    assert 0.13 < sea.significant_height_m < 0.16 and 1.1 < sea.peak_period_s < 1.3


def test_the_height_agrees_with_the_shore_protection_manuals_growth_law():
    """An independent law in U10 itself (Shore Protection Manual 1984, eq. 3-33: g H / U^2 = 1.6e-3 (g F / U^2)^(1/2))
    gives the CEM's friction-velocity law's height within 15% over fetches and winds a river or lake sees."""
    for wind, fetch in ((3.0, 500.0), (5.5, 3000.0), (10.0, 10000.0)):
        spm = 1.6e-3 * math.sqrt(GRAVITY * fetch / wind**2) * wind**2 / GRAVITY
        assert WindWaves(wind_mps=wind, fetch_m=fetch).significant_height_m == pytest.approx(spm, rel=0.15)


@settings(max_examples=50, deadline=None)
@given(st.floats(1.0, 25.0), st.floats(100.0, 20000.0))
def test_fetch_limited_growth_scales_as_the_root_and_the_cube_root_of_the_fetch(wind, fetch):
    a, b = WindWaves(wind_mps=wind, fetch_m=fetch), WindWaves(wind_mps=wind, fetch_m=4.0 * fetch)
    fully = 211.5 * a.friction_velocity_mps**2 / GRAVITY
    if b.significant_height_m < fully:
        assert b.significant_height_m / a.significant_height_m == pytest.approx(2.0, rel=1e-9)
        assert b.peak_period_s / a.peak_period_s == pytest.approx(4.0 ** (1.0 / 3.0), rel=1e-9)


def test_an_ocean_fetch_is_capped_at_the_fully_developed_sea():
    sea = WindWaves(wind_mps=10.0, fetch_m=1.0e6)
    u = sea.friction_velocity_mps
    assert sea.significant_height_m == pytest.approx(211.5 * u**2 / GRAVITY)
    assert sea.peak_period_s == pytest.approx(239.8 * u / GRAVITY)


def test_the_jonswap_spectrum_holds_the_significant_height_and_peaks_at_the_peak_frequency():
    hs, omega_p = 0.14, 2.0 * math.pi / 1.2
    m0 = quad(lambda w: float(jonswap(np.array([w]), hs, omega_p)[0]), 0.2 * omega_p, 20.0 * omega_p, limit=200)[0]
    assert 4.0 * math.sqrt(m0) == pytest.approx(hs, rel=1e-6)
    grid = np.linspace(0.5 * omega_p, 2.0 * omega_p, 30001)
    assert grid[np.argmax(jonswap(grid, hs, omega_p))] == pytest.approx(omega_p, rel=1e-3)
    assert not jonswap(grid, 0.0, omega_p).any()


def test_the_drawn_components_carry_nearly_all_of_the_seas_energy_and_repeat_with_the_seed():
    sea = WindWaves(wind_mps=5.5, fetch_m=3000.0)
    a = WaveMotion.from_wind(sea, np.random.default_rng(3), beam_m=0.0, length_m=0.0)  # no hull filter: the water's own heave
    assert 4.0 * math.sqrt(np.sum(a.heave_amp**2) / 2.0) == pytest.approx(sea.significant_height_m, rel=0.1)
    b = WaveMotion.from_wind(sea, np.random.default_rng(3))
    c = WaveMotion.from_wind(sea, np.random.default_rng(3))
    assert np.array_equal(b.roll_amp, c.roll_amp) and np.array_equal(b.phase, c.phase)
    assert np.abs(b.heave_amp).sum() < np.abs(a.heave_amp).sum()  # a 4.9 m hull rides over 2 m waves


@pytest.mark.parametrize("kwargs", [{"wind_mps": 0.0, "fetch_m": 1.0}, {"wind_mps": 5.0, "fetch_m": -1.0}, {"wind_mps": 5.0, "fetch_m": 1.0, "x": 1}])
def test_bad_wind_seas_are_refused(kwargs):
    with pytest.raises(ValidationError):
        WindWaves(**kwargs)
