"""Protection levels: the bound's analytic rule, the standard integrity figures, and bad settings refused."""

import math

import numpy as np
import pytest
from fusion_streams import StreamSpec, errors, generate, run
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import fusion
from fusion.integrity import kappa, protection_level
from scenarios.cli import app
from scenarios.score.metrics import integrity_metrics
from scenarios.spec.library import validate


def test_kappa_is_the_rayleigh_quantile():
    """For an isotropic error the circle of radius k sigma is left with probability exp(-k^2 / 2) exactly."""
    for risk in (1e-2, 1e-5, 1e-7):
        assert math.exp(-(kappa(risk) ** 2) / 2.0) == pytest.approx(risk, rel=1e-12)
    assert kappa(1e-5) == pytest.approx(4.7985, abs=1e-4)


@settings(max_examples=30, deadline=None)
@given(sx=st.floats(0.1, 5.0), sy=st.floats(0.1, 5.0), angle=st.floats(0.0, math.pi), seed=st.integers(0, 2**31))
def test_the_level_bounds_gaussian_errors_at_the_stated_risk(sx, sy, angle, seed):
    """Errors drawn from the covariance leave the level no more often than the risk allows (a binomial margin of
    4 sigma): exactly so when isotropic, conservatively otherwise."""
    risk, n = 0.01, 20000
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    cov = rot @ np.diag([sx**2, sy**2]) @ rot.T
    errors = np.random.default_rng(seed).multivariate_normal(np.zeros(2), cov, n)
    share = float(np.mean(np.hypot(errors[:, 0], errors[:, 1]) > protection_level(cov, risk)))
    assert share <= risk + 4.0 * math.sqrt(risk * (1 - risk) / n)


def test_a_non_finite_covariance_has_no_level_and_a_bad_risk_is_refused():
    assert math.isnan(protection_level(np.full((2, 2), np.inf), 1e-5))
    with pytest.raises(ValueError, match="integrity risk"):
        kappa(0.0)
    with pytest.raises(ValueError, match="integrity_risk"):
        fusion.create("ekf", integrity_risk=0.0)
    with pytest.raises(ValueError, match="integrity_risk"):
        fusion.create("pf", integrity_risk=1.5)
    with pytest.raises(ValueError, match="integrity_risk: Input should be a finite number"):  # not "less than 1"
        fusion.create("ekf", integrity_risk=math.nan)


def test_the_standard_figures_on_a_hand_counted_case():
    error = np.array([1.0, 5.0, 12.0, 3.0, np.nan])
    level = np.array([2.0, 4.0, 8.0, 12.0, 3.0])
    out = integrity_metrics(error, level, 10.0)
    assert out["misleading_epochs"] == 2 and out["misleading"] == pytest.approx(2 / 4)  # 5 > 4, 12 > 8
    assert out["hazardous_epochs"] == 1  # 12 m with the level at 8 m, under the 10 m alert limit
    assert out["available"] == pytest.approx(3 / 5)  # levels below 10 m over every scan (one had no estimate)
    assert out["hpl"]["max"] == 12.0
    none = integrity_metrics(error, np.full(5, np.nan), 10.0)
    assert math.isnan(none["misleading"]) and math.isnan(none["available"])


def test_the_ekf_reports_a_level_that_its_covariance_gives():
    from fusion.bootstrap import Alignment

    ekf = fusion.create("ekf", integrity_risk=1e-3)
    assert math.isnan(ekf.protection_level)
    ekf._initialise(Alignment(0.0, np.array([0.0, 0.0, 0.0]), np.diag([4.0, 1.0, 0.01])))
    assert ekf.protection_level == pytest.approx(kappa(1e-3) * 2.0)


@pytest.mark.parametrize("setting", ["integrity.alert_limit_m=0", "integrity.alert_limit_m=-3", "integrity.alert_limit_m=nan", "integrity.alert=10"])
def test_a_bad_alert_limit_is_one_line_and_exit_2(setting, tmp_path):
    result = CliRunner().invoke(app, ["run", "open_river", "--set", setting, "--out", str(tmp_path / "r")])
    assert result.exit_code == 2
    assert "integrity" in result.output and "Traceback" not in result.output
    with pytest.raises(ValueError, match="alert_limit_m"):
        validate({"name": "x", "world": "open_river", "integrity": {"alert_limit_m": 0}})


@settings(max_examples=50, deadline=None)
@given(rate_hz=st.sampled_from([5.0, 10.0, 20.0]), start=st.floats(0.0, 5000.0), n=st.integers(2, 300), seed=st.integers(0, 2**31))
def test_the_stanford_diagram_gives_each_pose_the_level_of_its_own_scan(rate_hz, start, n, seed):
    """scans.csv writes t to 1 ms and the TUM file to full precision: each pose still takes its own scan's level (at
    689ae21's parent, the next scan's or none: the demo's diagram held 1 epoch per estimator instead of 5,152)."""
    from scenarios.report.plots import RunSeries, Track, stanford_epochs

    rng = np.random.default_rng(seed)
    t = start + np.arange(n) / rate_hz + rng.uniform(0.0, 4e-4, n)  # the simulator's stamps: not on a ms grid
    level = rng.uniform(1.0, 50.0, n)
    keep = np.sort(rng.choice(n, size=max(1, n // 2), replace=False))  # the TUM file holds only scans with an estimate
    zero = np.zeros(n)
    truth = Track(t, zero, zero, zero)
    estimate = Track(t[keep], np.full(len(keep), 3.0), np.full(len(keep), 4.0), np.zeros(len(keep)))
    series = RunSeries(
        t0=float(t[0]),
        truth=truth,
        estimates={"ekf": estimate},
        matchers={},
        gps={},
        windows=[],
        hdop_limits={},
        scans={"t": np.round(t, 3), "ekf.hpl": level},
    )
    epochs = stanford_epochs(series, "ekf")
    assert epochs is not None
    np.testing.assert_allclose(epochs.level, level[keep])
    np.testing.assert_allclose(epochs.error, 5.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_pfs_covariance_carries_the_receivers_correlated_error_its_particles_cannot(seed):
    """Fixes whose whole error is one Gauss-Markov process (30 s, the host's own error model) pull the pf's cloud onto
    that error, which averaging them leaves; the reported covariance adds what the estimate took in of it (a consider
    covariance). Measured on these streams (6 seeds of 90 s): the cloud alone gave a mean NEES of 66 (chi-square 2 dof:
    2) and an error beyond the 1e-2 protection level three epochs in four; with the taken-in variance, 0.5-3.6 a seed."""
    events, t_grid, poses = generate(StreamSpec(duration=60.0, seed=seed, hdop=1.0))
    pf = fusion.create("pf", seed=seed)
    out = run(pf, events)
    err = errors(out, t_grid, poses)[:, :2]
    settled = (out["stamp"] > 20.0) & np.array([np.all(np.isfinite(c)) for c in out["cov"]])
    cov = out["cov"][settled][:, :2, :2]
    nees = np.einsum("ni,nij,nj->n", err[settled], np.linalg.inv(cov), err[settled])
    level = kappa(1e-2) * np.sqrt(np.linalg.eigvalsh(cov)[:, -1])
    assert 0.2 < nees.mean() < 6.0
    assert np.mean(np.hypot(*err[settled].T) > level) < 0.05
    cloud = pf._mean_cov(pf.poses, 2)[1][:2, :2]  # what the particles' spread alone says, at the end
    assert pf._taken > 10.0 * np.linalg.eigvalsh(cloud)[-1]
