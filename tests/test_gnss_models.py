"""GNSS building blocks: geodesy, WLS over random geometries, image method."""

from __future__ import annotations

import gnss_worlds as gw
import numpy as np
import pymap3d
import pytest
from analytic_worlds import wall_world
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sim import wls
from sim.geodesy import LocalFrame
from sim.multipath import FacadeIndex


@settings(max_examples=100, deadline=None)
@given(e=st.floats(-5000, 5000), n=st.floats(-5000, 5000), u=st.floats(-50, 500))
def test_geodetic_conversion_matches_pymap3d(e, n, u):
    frame = LocalFrame.at(*gw.ORIGIN)
    lat, lon, alt = frame.geodetic_of_enu(np.array([e, n, u]))
    ref = pymap3d.enu2geodetic(e, n, u, *gw.ORIGIN)
    assert lat == pytest.approx(float(ref[0]), abs=1e-10) and lon == pytest.approx(float(ref[1]), abs=1e-10)
    assert alt == pytest.approx(float(ref[2]), abs=1e-6)
    np.testing.assert_allclose(frame.enu_of_ecef(np.array([pymap3d.enu2ecef(e, n, u, *gw.ORIGIN)]))[0], [e, n, u], atol=1e-6)


@settings(max_examples=100, deadline=None)
@example(n_sats=4, seed=24, position=(2.0, 0.0, 0.0), clock=0.0)  # an ill-conditioned geometry CI once drew
@given(
    n_sats=st.integers(4, 12),
    seed=st.integers(0, 2**32 - 1),
    position=st.tuples(st.floats(-3000, 3000), st.floats(-3000, 3000), st.floats(-20, 100)),
    clock=st.floats(-3e5, 3e5),
)
def test_wls_recovers_position_and_clock_over_random_geometries(n_sats, seed, position, clock):
    rng = np.random.default_rng(seed)
    az = rng.uniform(0, 360, n_sats)
    el = rng.uniform(10, 90, n_sats)
    dirs = np.array([gw.direction(a, e) for a, e in zip(az, el)])
    q = wls.dop(dirs)
    if np.sqrt(np.trace(q[:3, :3])) > 50:  # near-degenerate geometry: no receiver would use it
        return
    truth = np.array(position)
    sats = truth + 2.2e7 * dirs
    pseudorange = np.linalg.norm(sats - truth, axis=1) + clock
    sol = wls.solve(sats, pseudorange, np.full(n_sats, 3.0), np.zeros(4))
    np.testing.assert_allclose(sol.enu, truth, atol=1e-3)
    assert sol.clock_m == pytest.approx(clock, abs=1e-3)
    # Q comes from the geometry at the start of the last (short) step, directions ~1e-7 rad off; the
    # inverse amplifies that as |Q|^2 (dQ = -Q dN Q), so the tolerance grows with the conditioning.
    tol = 1e-6 * max(1.0, np.abs(q).max()) ** 2
    np.testing.assert_allclose(sol.q, q, rtol=1e-5, atol=tol)
    np.testing.assert_allclose(sol.cov, 9.0 * q[:3, :3], rtol=1e-5, atol=9.0 * tol)


def test_wls_from_a_nearby_start_converges_in_one_step():
    dirs = np.array([gw.direction(a, e) for a, e in ((0, 80), (70, 30), (150, 45), (220, 20), (300, 35))])
    truth = np.array([120.0, -40.0, 1.3])
    sats = truth + 2.2e7 * dirs
    pseudorange = np.linalg.norm(sats - truth, axis=1) + 1234.5
    near = wls.solve(sats, pseudorange, np.full(5, 3.0), np.array([122.0, -41.0, 2.5, 1000.0]))
    assert near.iterations == 1 and np.linalg.norm(near.enu - truth) < 1e-4
    far = wls.solve(sats, pseudorange, np.full(5, 3.0), np.zeros(4))
    assert far.iterations >= 2 and np.linalg.norm(far.enu - truth) < 1e-4


def test_wls_needs_four_satellites():
    with pytest.raises(ValueError, match=">= 4 satellites"):
        wls.solve(np.ones((3, 3)), np.ones(3), np.ones(3), np.zeros(4))


@pytest.mark.parametrize("distance", [5.0, 12.0, 30.0])
def test_image_method_extra_path_off_a_wall(distance):
    # Wall face: the plane y = distance, x in [-100, 1100], z up to the wall top (normal -y).
    height = 6.0
    world = wall_world(distance_m=distance, height_m=height)
    index = FacadeIndex.from_world(world, radius_m=100.0)
    antenna = np.array([300.0, 0.0, 1.3])
    az = np.arange(100.0, 260.0, 7.0)  # southern sky: the wall is behind the antenna, its face towards it
    el = np.array([5.0, 10.0, 20.0, 35.0, 50.0])
    aa, ee = np.meshgrid(az, el)
    dirs = np.array([gw.direction(a, e) for a, e in zip(aa.ravel(), ee.ravel())])
    refl = index.reflections(antenna, dirs)
    ns = -dirs[:, 1]  # n . s with n = -y
    grazing = np.arcsin(ns)
    # The reflection meets the wall at height 1.3 + d tan(el) / cos(az - 180): inside the face if below the top.
    top = height  # wall_world: the box spans z in [-2, height]
    hit_height = 1.3 + distance * dirs[:, 2] / ns
    expected = hit_height <= top
    got = np.zeros(len(dirs), dtype=bool)
    got[refl.sat] = True
    np.testing.assert_array_equal(got, expected)
    assert expected.any() and (~expected).any() or distance == 5.0
    np.testing.assert_allclose(refl.extra_m, 2.0 * distance * np.sin(grazing[refl.sat]), rtol=1e-9)
    # For a vertical wall the grazing angle gives 2 d cos(el) cos(az - az_normal).
    el_r, az_r = np.deg2rad(ee.ravel()[refl.sat]), np.deg2rad(aa.ravel()[refl.sat] - 180.0)
    np.testing.assert_allclose(refl.extra_m, 2.0 * distance * np.cos(el_r) * np.cos(az_r), rtol=1e-9)
    np.testing.assert_allclose(refl.point[:, 1], distance, atol=1e-6)
    np.testing.assert_allclose(refl.point[:, 2], hit_height[refl.sat], atol=1e-6)
    # Satellites in the northern sky (behind the wall) have no reflection off it.
    north = np.array([gw.direction(a, 30.0) for a in (-60.0, 0.0, 60.0)])
    assert len(index.reflections(antenna, north)) == 0


def test_facade_search_is_bounded_by_the_radius():
    world = wall_world(distance_m=10.0)
    index = FacadeIndex.from_world(world, radius_m=50.0)
    assert len(index) > 0
    assert len(index.near(np.array([300.0, 0.0]))) > 0
    assert len(index.near(np.array([300.0, -100.0]))) == 0  # 110 m from the face
    far = index.reflections(np.array([300.0, -100.0, 1.3]), np.array([gw.direction(180.0, 20.0)]))
    assert len(far) == 0


def test_carrier_smoothing_restarts_at_reacquisition_and_averages_the_raw_noise_down():
    # sim.pseudorange.SmoothingLock: a satellite's smoothing restarts when its lock is lost; the residual of the raw
    # code's noise is the mean of the draws since lock (sigma_t / sqrt(k)), drifting from epoch to epoch
    from sim.pseudorange import PseudorangeNoise, SmoothingLock

    noise = PseudorangeNoise(white_zenith_m=0.15, restart_white_zenith_m=0.6)
    n = 4000
    lock = SmoothingLock(noise, n, np.random.default_rng(0))
    sats, tracked = np.arange(n), np.ones(n, bool)
    residual, factor = lock.update(sats, ~tracked)  # the first epoch: none tracked (a receiver starting under a deck)
    sigma_t = np.sqrt(0.6**2 - 0.15**2)
    series = []
    for k in range(1, 26):
        residual, factor = lock.update(sats, tracked)
        series.append(residual)
        assert np.std(residual) == pytest.approx(sigma_t / np.sqrt(k), rel=0.06)
        np.testing.assert_allclose(factor, np.sqrt(1.0 + (sigma_t / 0.15) ** 2 / k))
    assert np.corrcoef(series[-2], series[-1])[0, 1] > 0.95  # a mean: it drifts, it does not jump
    lost = np.zeros(n, bool)
    lost[: n // 2] = True  # half the satellites lose lock for an epoch, then come back
    residual, _ = lock.update(sats, ~lost)
    assert (residual[lost] == 0.0).all() and (lock.epochs[lost] == 0).all()
    residual, factor = lock.update(sats, tracked)
    assert np.std(residual[lost]) == pytest.approx(sigma_t, rel=0.06) and (lock.epochs[lost] == 1).all()
    assert np.std(residual[~lost]) == pytest.approx(sigma_t / np.sqrt(27), rel=0.08)
    warm = SmoothingLock(noise, 3, np.random.default_rng(0))  # tracked at the first epoch: smoothed for long already
    residual, factor = warm.update(np.arange(3), np.ones(3, bool))
    assert np.abs(residual).max() < 0.01 and np.allclose(factor, 1.0, atol=1e-3)
    off = SmoothingLock(PseudorangeNoise(white_zenith_m=0.15), 3, np.random.default_rng(0))  # no restart: nothing added
    residual, factor = off.update(np.arange(3), np.ones(3, bool))
    assert (residual == 0.0).all() and (factor == np.sqrt(1.0)).all()
