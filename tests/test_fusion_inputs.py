"""Estimators survive bad input with a recorded reason: out-of-order and NaN fixes, broken matches,
a matcher that always fails; and the registry names what is wrong."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from fusion_streams import StreamSpec, generate, run

import fusion
from matcher.result import MatchResult


@pytest.fixture(scope="module")
def clean():
    return generate(StreamSpec(duration=30.0, seed=2))


def _feed(est, events, until):
    for kind, stamp, payload in events:
        if stamp > until:
            break
        est.add_match(stamp, payload) if kind == "match" else est.add_fix(payload)


@pytest.mark.parametrize("name", fusion.available())
def test_out_of_order_and_nan_fixes_are_refused_with_a_reason(name, clean):
    events, _, _ = clean
    est = fusion.create(name)
    _feed(est, events, 20.0)
    before = est.pose.copy()
    fix = next(p for k, t, p in events if k == "fix" and t > 10.0)
    verdict = est.add_fix(fix)  # 10 s in the past
    assert not verdict.trusted and "out of order" in verdict.reason
    assert "out of order" in est.events[-1].reason
    t = est.stamp + 0.1
    bad = [
        dataclasses.replace(fix, stamp=t, enu=np.array([np.nan, 1.0, 0.0])),
        dataclasses.replace(fix, stamp=t, hdop=float("nan")),
        dataclasses.replace(fix, stamp=float("nan")),
        dataclasses.replace(fix, stamp=t, quality=9),
    ]
    for b, field in zip(bad, ("'enu'", "'hdop'", "'stamp'", "quality 9")):
        v = est.add_fix(b)
        assert not v.trusted and field in v.reason
        assert field in est.events[-1].reason
    assert np.allclose(est.pose[:2, 3], before[:2, 3], atol=1.0)  # only 0.1 s of coasting
    assert np.all(np.isfinite(est.pose))


@pytest.mark.parametrize("name", fusion.available())
def test_broken_matches_are_refused_with_a_reason(name, clean):
    events, _, _ = clean
    est = fusion.create(name)
    _feed(est, events, 20.0)
    t = est.stamp
    T_nan = np.eye(4)
    T_nan[0, 3] = np.nan
    cov_bad = -np.eye(6)
    cases = [
        (MatchResult(T=T_nan, ok=True, cov=np.eye(6) * 1e-4, n_points=100, seconds=0.0), "not a finite 4x4"),
        (MatchResult(T=np.eye(4), ok=True, cov=cov_bad, n_points=100, seconds=0.0), "not a finite 6x6 PSD"),
        (MatchResult.failure("blinded", gated=True), "blinded"),
    ]
    for i, (result, reason) in enumerate(cases):
        est.add_match(t + 0.1 * (i + 1), result)
        assert reason in est.events[-1].reason
    est.add_match(t - 5.0, cases[0][0])
    assert "out of order" in est.events[-1].reason
    assert np.all(np.isfinite(est.pose))


@pytest.mark.parametrize("name", fusion.available())
def test_matcher_that_always_fails_still_gives_a_gps_estimate(name):
    events, t_grid, poses = generate(StreamSpec(duration=30.0, failing_matcher=True, seed=4))
    est = fusion.create(name)
    out = run(est, events)
    assert est.initialized
    truth = poses[np.searchsorted(t_grid, out["stamp"][-1])]
    assert np.hypot(*(out["est"][-1, :2] - truth[:2])) < 6.0
    assert sum("always fails" in e.reason for e in est.events) >= 250


def test_registry_names_the_problem():
    assert fusion.available() == ["gps_only", "hdop_switch", "ekf", "pf"]
    with pytest.raises(ValueError, match="unknown estimator 'ukf'"):
        fusion.create("ukf")
    with pytest.raises(ValueError, match="estimator 'pf': unknown key 'n_particle'"):
        fusion.create("pf", n_particle=10)
    with pytest.raises(ValueError, match="estimator 'ekf': mount: must be a rigid transform"):
        fusion.create("ekf", mount=[[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    with pytest.raises(ValueError, match="unknown monitor 'raim'"):
        fusion.create("ekf", monitor="raim")
    with pytest.raises(ValueError, match="monitor 'nis': unknown key 'gate'"):
        fusion.create("pf", monitor="nis", monitor_params={"gate": 3})
    est = fusion.create("ekf", matcher="kiss_icp", monitor="nis")
    assert est.params.matcher == "kiss_icp" and est.monitor.name == "nis"
    assert np.isnan(est.pose).all() and np.isinf(est.cov).all()  # nothing known yet
