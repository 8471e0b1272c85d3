"""Matcher building blocks against analytic cases: registry, SE(3) algebra, de-skew, gate, covariance."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import matcher
from matcher.covariance import covariance_from_hessian
from matcher.gate import GateParams, ScanGate
from matcher.motion import (
    ConstantVelocity,
    deskew,
    deskew_planar,
    pose_to_xyzrpy,
    se3_exp,
    se3_log,
    xyzrpy_to_pose,
)
from matcher.pointplane import point_to_plane_fit

finite = st.floats(-1.0, 1.0, allow_nan=False)
twists = st.lists(finite, min_size=6, max_size=6).map(np.array)


# --- registry ------------------------------------------------------------------------------- #


def test_available_lists_the_four_matchers():
    assert matcher.available() == ["pcl6d", "bev3dof", "kiss_icp", "gicp"]


@pytest.mark.parametrize("name", ["pcl6d", "bev3dof", "kiss_icp", "gicp"])
def test_create_gives_a_fresh_matcher_with_documented_defaults(name):
    m = matcher.create(name)
    assert isinstance(m, matcher.Matcher)
    assert m.name == name
    model = matcher.params_model(name)
    for field, info in model.model_fields.items():
        assert info.description, f"{name}.{field} has no documented default"


def test_unknown_matcher_is_a_value_error_naming_it():
    with pytest.raises(ValueError, match="'sift3d'"):
        matcher.create("sift3d")


def test_unknown_parameter_is_a_value_error_naming_it():
    with pytest.raises(ValueError, match="voxel_size_typo"):
        matcher.create("gicp", voxel_size_typo=0.3)


def test_bad_parameter_value_is_a_value_error_naming_it():
    with pytest.raises(ValueError, match="pixel_m"):
        matcher.create("bev3dof", pixel_m=-0.1)
    with pytest.raises(ValueError, match="prealign"):
        matcher.create("pcl6d", prealign="teaser")


# --- SE(3) and de-skew ---------------------------------------------------------------------- #


@given(twists)
def test_se3_log_inverts_exp(xi):
    np.testing.assert_allclose(se3_log(se3_exp(xi)), xi, atol=1e-9)


@given(st.lists(finite, min_size=6, max_size=6))
def test_xyzrpy_round_trip(p):
    p = np.array(p) * [10, 10, 10, 1.5, 1.5, 3.0]
    np.testing.assert_allclose(pose_to_xyzrpy(xyzrpy_to_pose(p)), p, atol=1e-9)


@settings(max_examples=50)
@given(twists, st.integers(0, 2**31 - 1))
def test_deskew_applies_the_constant_velocity_pose_at_each_firing_time(xi, seed):
    rng = np.random.default_rng(seed)
    xyz = rng.uniform(-50, 50, (20, 3))
    t = rng.uniform(0, 0.1, 20)
    twist = xi * [5, 5, 1, 1, 1, 2]
    expected = np.array([(se3_exp(twist * ti) @ np.r_[p, 1.0])[:3] for p, ti in zip(xyz, t)])
    np.testing.assert_allclose(deskew(xyz, t, twist), expected, atol=1e-9)


@given(twists)
def test_planar_deskew_matches_the_full_one_for_a_planar_twist(xi):
    twist = np.array([xi[0] * 3, xi[1], 0.0, 0.0, 0.0, xi[5]])
    rng = np.random.default_rng(0)
    xyz = rng.uniform(-40, 40, (30, 3))
    t = rng.uniform(0, 0.1, 30)
    np.testing.assert_allclose(deskew_planar(xyz[:, :2], t, twist), deskew(xyz, t, twist)[:, :2], atol=1e-9)


def test_deskew_without_a_twist_leaves_points_alone():
    xyz = np.ones((3, 3))
    assert deskew(xyz, np.zeros(3), None) is xyz


def test_constant_velocity_predicts_scaled_motion():
    cv = ConstantVelocity()
    np.testing.assert_array_equal(cv.predict(0.1), np.eye(4))
    T = xyzrpy_to_pose(np.array([0.2, 0.01, 0.0, 0.0, 0.0, 0.02]))
    cv.update(T, 0.1)
    np.testing.assert_allclose(cv.predict(0.1), T, atol=1e-12)
    np.testing.assert_allclose(cv.predict(0.2), T @ T, atol=1e-12)


# --- the scan gate --------------------------------------------------------------------------- #


def test_gate_drops_too_few_points_and_count_jumps():
    gate = ScanGate(GateParams(gate_min_points=100, gate_max_ratio=2.0, gate_window=3, gate_reset_after=3))
    assert not gate.check(50).ok and "gate_min_points" in gate.check(50).reason
    for n in (1000, 1100, 900):
        assert gate.check(n).ok
    v = gate.check(100)
    assert not v.ok and "point count jump" in v.reason
    assert not gate.check(2500).ok
    assert gate.check(1900).ok  # within a factor 2 of the median 1000
    assert gate.reference_count == 1100.0  # median of the last three accepted: 1100, 900, 1900


def test_gate_accepts_a_lasting_change_of_level():
    gate = ScanGate(GateParams(gate_min_points=10, gate_max_ratio=2.0, gate_window=5, gate_reset_after=3))
    assert gate.check(1000).ok
    assert [gate.check(5000).ok for _ in range(3)] == [False, False, True]
    assert gate.reference_count == 5000.0 and gate.check(4800).ok


# --- covariance and degeneracy --------------------------------------------------------------- #


def test_covariance_of_a_well_conditioned_hessian_is_sigma2_h_inverse():
    rng = np.random.default_rng(1)
    J = rng.normal(size=(500, 6))
    H = J.T @ J
    cov, deg = covariance_from_hessian(H, 1e-4, 0.01, 1.0, 0.1)
    np.testing.assert_allclose(cov, 1e-4 * np.linalg.inv(H), rtol=1e-9, atol=1e-15)
    assert not deg.as_info()["degenerate"]


def test_an_unconstrained_direction_is_flagged_and_inflated():
    H = np.diag([1e-3, 1e4, 1e4, 1e5, 1e5, 1e5])  # x (along a canal) barely constrained
    cov, deg = covariance_from_hessian(H, 1e-4, 0.01, 1.0, 0.1)
    info = deg.as_info()
    assert info["degenerate"]
    assert len(info["degenerate_directions"]) == 1
    np.testing.assert_allclose(np.abs(info["degenerate_directions"][0]), [1, 0, 0, 0, 0, 0], atol=1e-12)
    assert cov[0, 0] == pytest.approx(1.0)  # raised to degenerate_sigma_m^2 (and no more)
    assert cov[1, 1] == pytest.approx(1e-8)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_rotations_are_judged_among_rotations():
    H = np.diag([1e4, 1e4, 1e4, 1e6, 1e6, 1e1])  # yaw free; translations fine despite smaller values
    cov, deg = covariance_from_hessian(H, 1e-4, 0.01, 1.0, 0.1)
    dirs = np.abs(np.array(deg.as_info()["degenerate_directions"]))
    np.testing.assert_allclose(dirs, [[0, 0, 0, 0, 0, 1]], atol=1e-12)
    assert cov[5, 5] == pytest.approx(0.01) and cov[0, 0] == pytest.approx(1e-8)


def test_point_to_plane_information_of_a_corner():
    """Three orthogonal planes constrain all six directions; a single wall only its normal."""
    g = np.linspace(-5, 5, 21)
    a, b = [v.ravel() for v in np.meshgrid(g, g)]
    zero = np.zeros_like(a)
    walls = [np.c_[a, b, zero - 6], np.c_[zero + 8, a, b], np.c_[a, zero - 9, b]]  # apart: no shared points
    normals = [np.tile(n, (len(a), 1)) for n in ([0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0])]
    pts, nrm = np.vstack(walls), np.vstack(normals)
    fit = point_to_plane_fit(pts, np.eye(4), pts, nrm, cKDTree(pts), 0.5, 0.1)
    J = np.hstack([nrm, np.cross(pts, nrm)])
    np.testing.assert_allclose(fit.H, J.T @ J, rtol=1e-12)
    assert fit.fitness == 1.0 and fit.outlier_share == 0.0
    assert np.linalg.matrix_rank(fit.H) == 6
    one = point_to_plane_fit(walls[1], np.eye(4), walls[1], normals[1], cKDTree(walls[1]), 0.5, 0.1)
    translation_info = np.linalg.eigvalsh(one.H[:3, :3])
    assert np.sum(translation_info > 1e-9) == 1


def test_point_to_plane_outlier_share_counts_residuals_beyond_the_kernel():
    g = np.linspace(-5, 5, 11)
    a, b = [v.ravel() for v in np.meshgrid(g, g)]
    target = np.c_[a, b, np.zeros_like(a)]
    source = target.copy()
    source[:10, 2] = 0.3  # 10 of 121 points 30 cm off the plane
    fit = point_to_plane_fit(source, np.eye(4), target, np.tile([0, 0, 1.0], (len(a), 1)), cKDTree(target), 1.0, 0.1)
    assert fit.outlier_share == pytest.approx(10 / 121)
    assert fit.sigma2 == pytest.approx(0.0)  # Tukey gives the outliers zero weight


@settings(max_examples=100)
@given(st.lists(st.integers(0, 40000), min_size=1, max_size=40), st.floats(1.2, 4.0), st.integers(1, 6), st.integers(1, 4))
def test_gate_verdicts_follow_the_rule(counts, ratio, window, reset_after):
    """Accepted: enough points and within `ratio` of the recent accepted median, or a lasting change."""
    gate = ScanGate(GateParams(gate_min_points=300, gate_max_ratio=ratio, gate_window=window, gate_reset_after=reset_after))
    accepted: list[int] = []
    drops = 0
    for n in counts:
        verdict = gate.check(n)
        if n < 300:
            assert not verdict.ok
            continue
        ref = float(np.median(accepted[-window:])) if accepted else None
        within = ref is None or max(n / ref, ref / n) <= ratio
        drops = 0 if within else drops + 1
        assert verdict.ok == (within or drops >= reset_after)
        if verdict.ok:
            accepted = accepted if within else []
            accepted.append(n)
            drops = 0
