"""Monitor 'cn0': NLOS satellites (C/N0 below a template learned online) flag the fix; clean ones do not.

Synthetic receiver: C/N0 = horizon + (zenith - horizon) sin(el) + N(0, 1 dB) for a direct signal,
8 dB less for a reflected-only (NLOS) one, as the field's receivers and the bench's simulator do;
the monitor never sees these constants, it learns them from the fixes.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.stats import norm

import fusion
import scenarios
from fusion import monitors
from fusion.monitors import FixContext
from fusion.monitors.cn0 import per_satellite_gate
from fusion.monitors.satellite_geometry import horizontal_slopes
from fusion.observation import screen
from fusion.odometry import OdometryTrack
from scenarios.pipeline.assembly import assemble
from scenarios.replay import nmea_log
from sim.gnss_fix import GnssFix, SatelliteReport

HORIZON_DBHZ, ZENITH_DBHZ, JITTER_DB, NLOS_LOSS_DB = 35.0, 50.0, 1.0, 8.0
CTX = FixContext(predicted=None, yaw=None, yaw_var=None, lever=np.zeros(2), odometry=OdometryTrack())


def make_fix(t: float, el_deg, snr, used=None) -> GnssFix:
    """A GGA-1 fix at the origin carrying these satellite reports (GSV/GSA fields)."""
    el_deg, snr = np.asarray(el_deg, float), np.asarray(snr, float)
    used = np.ones(len(el_deg), bool) if used is None else np.asarray(used, bool)
    az = (np.arange(len(el_deg)) * 137.5) % 360.0
    sats = tuple(SatelliteReport(int(i + 1), float(a), float(e), float(s), bool(u)) for i, (a, e, s, u) in enumerate(zip(az, el_deg, snr, used)))
    return GnssFix(
        stamp=t, lat=42.35, lon=-71.11, alt=0.0, enu=np.zeros(3), quality=1, num_sats=int(used.sum()), hdop=1.0, vdop=1.5, pdop=1.8, sats=sats
    )


def direct_cn0(el_deg, rng, offset_db=0.0) -> np.ndarray:
    el_deg = np.asarray(el_deg, float)
    return HORIZON_DBHZ + offset_db + (ZENITH_DBHZ - HORIZON_DBHZ) * np.sin(np.deg2rad(el_deg)) + JITTER_DB * rng.standard_normal(el_deg.shape)


def feed(mon, fix: GnssFix):
    """Judge a fix and let the monitor learn from it, as an estimator does."""
    obs, why = screen(fix, 3.0, False)
    assert obs is not None, why
    verdict = mon.check(obs, CTX)
    mon.commit(obs, verdict)
    return verdict


def clean_epochs(rng, n: int, offset_db=0.0, nlos_share=0.0, n_sats=10):
    """n epochs of n_sats satellites at random elevations 5-88 deg; a share of them NLOS (8 dB weaker)."""
    out = []
    for k in range(n):
        el = rng.uniform(5.0, 88.0, n_sats)
        snr = direct_cn0(el, rng, offset_db) - NLOS_LOSS_DB * (rng.random(n_sats) < nlos_share)
        out.append((0.2 * k, el, snr))
    return out


def warmed(seed=0, offset_db=0.0, nlos_share=0.0, n=400):
    mon = monitors.create("cn0")
    for t, el, snr in clean_epochs(np.random.default_rng(seed), n, offset_db, nlos_share):
        feed(mon, make_fix(t, el, snr))
    return mon


@pytest.fixture(scope="module")
def learned():
    return warmed()


def test_learns_the_template_and_its_jitter(learned):
    el = np.array([10.0, 30.0, 60.0, 85.0])
    expected, sigma = learned.template(el)
    truth = HORIZON_DBHZ + (ZENITH_DBHZ - HORIZON_DBHZ) * np.sin(np.deg2rad(el))
    assert np.max(np.abs(expected - truth)) < 0.4
    assert 0.75 < sigma < 1.3


def test_weak_used_satellites_flag_the_fix_and_are_named(learned):
    rng = np.random.default_rng(1)
    el = np.array([12.0, 25.0, 40.0, 55.0, 70.0, 80.0, 33.0, 18.0])
    snr = direct_cn0(el, rng)
    snr[[2, 5]] -= NLOS_LOSS_DB
    verdict = learned.check(screen(make_fix(100.0, el, snr), 3.0, False)[0], CTX)
    assert not verdict.trusted
    assert 5.0 < verdict.statistic < 11.0
    assert "PRN 3" in verdict.reason and "PRN 6" in verdict.reason and "PRN 1 " not in verdict.reason


def test_satellite_deficits_are_the_verdicts_evidence_per_used_satellite(learned):
    rng = np.random.default_rng(1)
    el = np.array([12.0, 25.0, 40.0, 55.0, 70.0, 80.0])
    snr = direct_cn0(el, rng)
    snr[2] -= NLOS_LOSS_DB
    used = np.array([True, True, True, True, False, True])
    obs = screen(make_fix(100.0, el, snr, used), 3.0, False)[0]
    deficits, sats, sigma, note = learned.satellite_deficits(obs)
    expected, _ = learned.template(el[used])
    assert [s.prn for s in sats] == [1, 2, 3, 4, 6] and note == ""
    np.testing.assert_allclose(deficits, (expected - snr[used]) / sigma)
    level = per_satellite_gate(learned.gate, len(deficits))  # the fix's gate (family_gate), in each satellite's sigma
    assert int(np.argmax(deficits)) == 2 and deficits[2] > level
    assert learned.check(obs, CTX).statistic == pytest.approx(deficits.max() * learned.gate / level)
    assert monitors.create("cn0").satellite_deficits(obs).startswith("learning the C/N0 template")


def test_a_weak_satellite_the_receiver_did_not_use_is_harmless(learned):
    rng = np.random.default_rng(2)
    el = np.array([12.0, 25.0, 40.0, 55.0, 70.0, 80.0])
    snr = direct_cn0(el, rng)
    snr[1] -= NLOS_LOSS_DB
    used = np.array([True, False, True, True, True, True])
    assert learned.check(screen(make_fix(100.0, el, snr, used), 3.0, False)[0], CTX).trusted


@given(gate=st.floats(1.0, 6.0), n=st.integers(1, 60))
def test_the_gate_holds_for_the_fix_whatever_its_satellites(gate, n):
    # Sidak: the largest of n direct signals' deficits exceeds each one's level with the probability one exceeds the gate
    level = per_satellite_gate(gate, n)
    assert -math.expm1(n * math.log1p(-norm.sf(level))) == pytest.approx(norm.sf(gate), rel=1e-6)
    assert level >= gate and (n == 1) == (level == gate)
    assert per_satellite_gate(gate, n + 1) > level


def test_the_largest_of_many_direct_deficits_passes_the_fix_gate_at_its_rate():
    # Monte Carlo of the verdict's statistic on direct signals alone: 16 standard normal deficits per fix
    deficits = np.random.default_rng(4).standard_normal((400_000, 16))
    gate = 3.0  # 1.35e-3 a fix: measurable in 4e5 fixes (the default 4 sigma, 3e-5, would need 1e7)
    over = (deficits.max(axis=1) > per_satellite_gate(gate, 16)).mean()
    assert over == pytest.approx(norm.sf(gate), rel=0.1)  # 540 expected, 10%: 2.3 of its Poisson sigma (a seeded draw)
    assert (deficits.max(axis=1) > gate).mean() > 10 * norm.sf(gate)  # the per-satellite gate alone: 16 times as often


def test_clean_fixes_pass_at_the_nominal_false_alarm_rate(learned):
    # gate 4 sigma for the fix (family_gate): 3e-5 per fix of direct signals; allow the template's estimation error
    rng = np.random.default_rng(3)
    verdicts = [
        learned.check(screen(make_fix(100.0 + 0.2 * k, el, snr), 3.0, False)[0], CTX) for k, (_, el, snr) in enumerate(clean_epochs(rng, 3000))
    ]
    assert np.mean([not v.trusted for v in verdicts]) < 0.003


@pytest.mark.parametrize("hold_s", [0.0, 6.0])
def test_an_nlos_fix_is_held_for_hold_s_as_the_receiver_filter_still_carries_it(hold_s):
    mon = monitors.create("cn0", hold_s=hold_s)
    rng = np.random.default_rng(9)
    for t, el, snr in clean_epochs(rng, 400):
        feed(mon, make_fix(t, el, snr))
    el = np.array([15.0, 35.0, 50.0, 65.0, 80.0])
    snr = direct_cn0(el, rng)
    snr[1] -= 2 * NLOS_LOSS_DB
    flagged = feed(mon, make_fix(100.0, el, snr))
    assert not flagged.trusted and flagged.rule == "cn0.deficit"
    after = {round(0.2 * k, 1): feed(mon, make_fix(100.0 + 0.2 * k, el, direct_cn0(el, rng))) for k in range(1, 40)}
    for dt, verdict in after.items():
        if dt == hold_s:
            continue  # on the boundary, float rounding decides
        held = dt < hold_s
        assert verdict.trusted != held, (dt, verdict.reason)
        if held:
            assert verdict.statistic == flagged.statistic and "within 6 s" in verdict.reason and verdict.rule == "cn0.hold"
        else:
            assert verdict.statistic < mon.gate and verdict.rule == ""


def _ten_metre_suspect(**params):
    """A cn0 monitor (hold_s 6 s, `params`) warmed on clean epochs, then fed a fix whose 35 deg satellite is reflected and
    could move it by 10 m (nlos_bias_m x cos(35 deg) x its slope): (the monitor, the elevations, the rng, the verdict on
    that fix)."""
    from fusion.monitors.satellite_geometry import horizontal_slopes

    el = np.array([15.0, 35.0, 50.0, 65.0, 80.0])
    az = (np.arange(len(el)) * 137.5) % 360.0  # make_fix's azimuths
    slope = horizontal_slopes(el, az, ["GPS"] * len(el))[1]
    mon = monitors.create("cn0", hold_s=6.0, nlos_bias_m=10.0 / (slope * np.cos(np.deg2rad(el[1]))), **params)
    rng = np.random.default_rng(9)
    for t, e, snr in clean_epochs(rng, 400):
        feed(mon, make_fix(t, e, snr))
    snr = direct_cn0(el, rng)
    snr[1] -= 2 * NLOS_LOSS_DB
    return mon, el, rng, feed(mon, make_fix(100.0, el, snr))


@pytest.mark.parametrize("half_life_s", [4.0, None])
def test_a_held_fault_counts_while_its_halving_effect_could_still_move_the_fix_by_a_fault(half_life_s):
    """Analytic: a suspect that could move the fix by 10 m (nlos_bias_m x its slope) is held while 10 m x 0.5^(age /
    half-life) > fault_m 5 m, i.e. for one half-life (4 s of the 6 s hold); without a half-life for the whole hold."""
    mon, el, rng, flagged = _ten_metre_suspect(hold_half_life_s=half_life_s, fault_m=5.0)
    assert not flagged.trusted and "can move the fix 10.0 m" in flagged.reason
    carried_s = 6.0 if half_life_s is None else half_life_s  # 10 x 0.5^(age / half-life) = 5 at one half-life
    for k in range(1, 40):
        dt = round(0.2 * k, 1)
        verdict = feed(mon, make_fix(100.0 + dt, el, direct_cn0(el, rng)))
        if abs(dt - carried_s) > 1e-9:  # on the boundary, float rounding decides
            assert verdict.trusted == (dt > carried_s), (dt, verdict.reason)


@settings(max_examples=40, deadline=None)
@given(distance_m=st.floats(0.0, 6.0), sigma_m=st.floats(0.01, 2.0))
def test_with_certify_z_a_suspect_fix_the_prediction_bounds_below_the_fault_is_trusted_with_that_bound(distance_m, sigma_m):
    """Analytic: a fix a 10 m suspect makes the monitor refuse is trusted when its distance from the host's predicted fix
    plus certify_z x the prediction's largest sigma is below fault_m, with that bound as its allowance (rule
    cn0.certified); otherwise refused as before."""
    mon, el, rng, flagged = _ten_metre_suspect(certify_z=3.7)  # fed without a prediction: refused
    assert not flagged.trusted and flagged.rule == "cn0.deficit"
    snr = direct_cn0(el, rng)
    snr[1] -= 2 * NLOS_LOSS_DB
    obs = screen(make_fix(100.2, el, snr), 3.0, False)[0]
    predicted = (obs.xy + np.array([distance_m, 0.0]), np.diag([sigma_m**2, (0.5 * sigma_m) ** 2]), np.eye(2))
    verdict = mon.check(obs, dataclasses.replace(CTX, predicted=predicted))
    bound = distance_m + 3.7 * sigma_m
    if abs(bound - 5.0) > 1e-9:
        assert verdict.trusted == (bound < 5.0), verdict.reason
        assert verdict.rule == ("cn0.certified" if bound < 5.0 else "cn0.deficit")
        assert verdict.allowance_m == (pytest.approx(bound) if bound < 5.0 else 0.0)


def test_with_hold_allowance_a_held_fix_is_trusted_allowing_what_the_fault_could_still_move_it():
    """Analytic: a suspect that could move the fix by 10 m; with hold_allowance the fix carrying it is still refused (its
    own satellite is low), the held ones after it are trusted with an allowance of 10 m x 0.5^(age / 4 s) (the receiver
    filter's half-life), named cn0.hold, until the 6 s hold ends; then trusted outright."""
    from fusion.monitors.cn0 import RECEIVER_HALF_LIFE_S

    mon, el, rng, flagged = _ten_metre_suspect(hold_allowance=True)
    assert not flagged.trusted and flagged.rule == "cn0.deficit" and flagged.allowance_m == 0.0
    for k in range(1, 40):
        dt = round(0.2 * k, 1)
        verdict = feed(mon, make_fix(100.0 + dt, el, direct_cn0(el, rng)))
        assert verdict.trusted, (dt, verdict.reason)
        if dt < 6.0 - 1e-9:
            assert verdict.rule == "cn0.hold" and verdict.allowance_m == pytest.approx(10.0 * 0.5 ** (dt / RECEIVER_HALF_LIFE_S), rel=1e-9)
        elif dt > 6.0 + 1e-9:
            assert verdict.rule == "" and verdict.allowance_m == 0.0


def test_learning_survives_nlos_in_the_training_data():
    mon = warmed(seed=4, nlos_share=0.15)
    rng = np.random.default_rng(5)
    clean = [mon.check(screen(make_fix(100.0, el, snr), 3.0, False)[0], CTX).trusted for _, el, snr in clean_epochs(rng, 1000)]
    assert np.mean(clean) > 0.99
    el = np.array([15.0, 35.0, 50.0, 65.0, 80.0])
    snr = direct_cn0(el, rng)
    snr[0] -= NLOS_LOSS_DB
    assert not mon.check(screen(make_fix(100.0, el, snr), 3.0, False)[0], CTX).trusted


@pytest.mark.parametrize("offset_db", [-5.0, 5.0])
def test_template_is_learned_not_assumed(offset_db):
    # the same jitter draws on a receiver 5 dB hotter or colder: identical verdicts after warm-up
    base, shifted = monitors.create("cn0"), monitors.create("cn0")
    rng = np.random.default_rng(6)
    for k, (t, el, snr) in enumerate(clean_epochs(rng, 700, nlos_share=0.05)):
        if k == 600:
            snr[:2] -= NLOS_LOSS_DB  # an NLOS pair mid-stream
        a, b = feed(base, make_fix(t, el, snr)), feed(shifted, make_fix(t, el, snr + offset_db))
        assert a.trusted == b.trusted
        if k >= 400:
            assert "learning" not in a.reason
            assert a.statistic == pytest.approx(b.statistic, abs=1e-6)
    assert not feed(base, make_fix(999.0, [20.0, 50.0, 70.0], direct_cn0([20.0, 50.0, 70.0], rng) - [NLOS_LOSS_DB, 0, 0])).trusted


def test_during_warm_up_it_says_it_is_learning():
    mon = monitors.create("cn0")
    v = feed(mon, make_fix(0.0, [20.0, 40.0, 60.0], [38.0, 44.0, 47.0]))
    assert v.trusted and math.isnan(v.statistic) and "learning the C/N0 template" in v.reason


@settings(max_examples=60, deadline=None)
@given(
    geometry=st.lists(st.tuples(st.floats(6.0, 89.0), st.booleans(), st.booleans(), st.floats(-2.0, 2.0)), min_size=1, max_size=14),
    loss_db=st.floats(7.0, 12.0),
)
@example(geometry=[(6.0, True, True, 0.0), (7.0, False, True, 0.0), (7.0, False, True, 0.0), (7.0, False, True, 0.0)], loss_db=7.0)
def test_flagged_exactly_when_a_used_satellite_is_nlos_and_could_move_the_fix(learned, geometry, loss_db):
    # within +-2 dB of the template a direct signal passes; 7 dB or more below it, a suspect, which refuses the fix when
    # the suspects could move it by more than fault_m (nlos_bias_m cos(el) of extra path each, times its slope): four
    # satellites at 6-7 deg put a bias on the lowest into the height and clock, not the horizontal fix (hypothesis found it)
    el = np.array([g[0] for g in geometry])
    nlos = np.array([g[1] for g in geometry])
    used = np.array([g[2] for g in geometry])
    snr = HORIZON_DBHZ + (ZENITH_DBHZ - HORIZON_DBHZ) * np.sin(np.deg2rad(el)) + np.array([g[3] for g in geometry]) - loss_db * nlos
    fix = make_fix(100.0, el, snr, used)
    verdict = learned.check(screen(fix, 3.0, False)[0], CTX)
    p, suspects = learned.params, (nlos & used)[used]
    harmful = False
    if suspects.any():
        slopes = horizontal_slopes(el[used], np.array([s.az_deg for s in fix.sats])[used], ["GPS"] * int(used.sum()))
        harmful = float(np.sum((slopes * p.nlos_bias_m * np.cos(np.deg2rad(el[used])))[suspects])) > p.fault_m
    assert verdict.trusted == (not harmful)
    if used.any():
        deficits = ((learned.template(el)[0] - snr) / learned.template(el)[1])[used]
        counted = deficits if harmful or not suspects.any() else deficits[~suspects]
        largest = counted.max() if counted.size else 0.0
        assert verdict.statistic == pytest.approx(largest * learned.gate / per_satellite_gate(learned.gate, int(used.sum())))


def test_bad_reports_are_skipped_with_a_reason(learned):
    el = [20.0, 40.0, 60.0, 75.0]
    snr = direct_cn0(el, np.random.default_rng(7))
    snr[1] = math.nan
    v = learned.check(screen(make_fix(100.0, el, snr), 3.0, False)[0], CTX)
    assert v.trusted and "skipped PRN 2" in v.reason
    v = learned.check(screen(make_fix(100.0, el, [math.nan] * 4), 3.0, False)[0], CTX)
    assert v.trusted and math.isnan(v.statistic) and "no used satellite with a valid C/N0" in v.reason
    v = learned.check(screen(make_fix(100.0, [], []), 3.0, False)[0], CTX)
    assert v.trusted and math.isnan(v.statistic) and "no used satellite reported" in v.reason
    before = learned.template(30.0)
    feed(learned, make_fix(100.0, el, [math.nan, -1.0, 0.0, math.inf]))  # nothing learnable: template unchanged
    assert learned.template(30.0) == before


def test_an_estimator_runs_it_on_bad_fixes_without_crashing():
    est = fusion.create("ekf", monitor="cn0")
    rng = np.random.default_rng(8)
    for t, el, snr in clean_epochs(rng, 50):
        snr[0] = math.nan
        verdict = est.add_fix(make_fix(t, el, snr))
        assert "skipped PRN 1" in verdict.reason or not verdict.trusted


def test_parameters_are_validated_by_name():
    with pytest.raises(ValueError, match="monitor 'cn0': gate_sigma: Input should be greater than 0"):
        monitors.create("cn0", gate_sigma=0)
    with pytest.raises(ValueError, match="high_q"):
        monitors.create("cn0", mid_q=0.9, high_q=0.8)
    with pytest.raises(ValueError, match="'bin_count'"):
        monitors.create("cn0", bin_count=4)
    for bad in (-5.0, math.nan, math.inf):  # a NaN bias would weigh every suspect harmless, silently
        with pytest.raises(ValueError, match="monitor 'cn0': nlos_bias_m"):
            monitors.create("cn0", nlos_bias_m=bad)
    for bad in (0.0, math.nan):
        with pytest.raises(ValueError, match="monitor 'cn0': fault_m"):
            monitors.create("cn0", fault_m=bad)
    mon = monitors.create("combined", members=["nis", "consistency", "cn0"])
    assert [m.name for m in mon.members] == ["nis", "consistency", "cn0"]


def test_combined_cn0_is_registered_and_the_ekf_default():
    mon = monitors.create("combined_cn0")
    assert [m.name for m in mon.members] == ["consistency", "cn0"]
    with pytest.raises(ValueError, match="cannot contain 'combined'"):
        monitors.create("combined_cn0", members=["cn0", "combined"])
    est = fusion.create("ekf")
    assert est.params.monitor == "combined_cn0"
    # end to end through the estimator: after warm-up a fix that uses an 8 dB weak satellite is refused
    rng = np.random.default_rng(9)
    for t, el, snr in clean_epochs(rng, 300):
        est.add_fix(make_fix(t, el, snr))
    el = np.array([15.0, 35.0, 50.0, 65.0, 80.0])
    snr = direct_cn0(el, rng)
    snr[2] -= NLOS_LOSS_DB
    verdict = est.add_fix(make_fix(60.0, el, snr))
    assert not verdict.trusted and "cn0: C/N0 deficit" in verdict.reason and "PRN 3" in verdict.reason


# ------------------------------------------------------------------------- real receivers: several constellations and signals

SIGNALS = (("GPS", "L1 C/A", 0.0, 8), ("GLONASS", "L1OF", -3.0, 7), ("Galileo", "E1-BC", 2.0, 6))
"""(system, signal, its true C/N0 offset from GPS L1 C/A (dB), satellites per epoch) of a synthetic multi-GNSS receiver."""


def multi_fix(t: float, rng, nlos: tuple[str, int] | None = None, loss_db: float = NLOS_LOSS_DB) -> GnssFix:
    """A multi-GNSS fix: each signal's satellites at random elevations, direct (its own offset, 1 dB jitter) but `nlos`."""
    sats = []
    for system, signal, offset, n in SIGNALS:
        el = rng.uniform(5.0, 88.0, n)
        snr = direct_cn0(el, rng, offset)
        if nlos is not None and nlos[0] == system:
            snr[nlos[1]] -= loss_db
        sats += [SatelliteReport(k + 1, float(45 * k % 360), float(e), float(c), True, system, signal) for k, (e, c) in enumerate(zip(el, snr))]
    return GnssFix(
        stamp=t, lat=42.35, lon=-71.11, alt=0.0, enu=np.zeros(3), quality=1, num_sats=len(sats), hdop=1.0, vdop=1.5, pdop=1.8, sats=tuple(sats)
    )


def test_gps_l1_only_reports_take_the_single_template_path():
    """The simulator's receiver (GPS L1 C/A only): per-signal expectations change nothing, to the last bit."""
    a, b = monitors.create("cn0"), monitors.create("cn0", per_signal=False)
    for t, el, snr in clean_epochs(np.random.default_rng(10), 600, nlos_share=0.1):
        va, vb = feed(a, make_fix(t, el, snr)), feed(b, make_fix(t, el, snr))
        assert (va.trusted, va.reason) == (vb.trusted, vb.reason)
        assert va.statistic == vb.statistic or (math.isnan(va.statistic) and math.isnan(vb.statistic))
    assert a.template(30.0) == b.template(30.0) and a.offsets() == {"GPS L1 C/A": 0.0}


def test_each_signals_offset_is_learned_clean_fixes_pass_and_reflections_are_caught():
    rng = np.random.default_rng(11)
    # the C/N0 test alone (suspects not weighed by how far they move the fix): every reflection is a suspect to catch
    after, before = monitors.create("cn0", nlos_bias_m=0), monitors.create("cn0", per_signal=False, nlos_bias_m=0)
    for k in range(300):
        fix = multi_fix(0.2 * k, rng)
        feed(after, fix), feed(before, fix)
    learned = after.offsets()
    for system, signal, offset, _ in SIGNALS:
        assert learned[f"{system} {signal}"] == pytest.approx(offset, abs=0.6)
    assert after.template(30.0)[1] < 1.2 < 1.5 < before.template(30.0)[1]  # one template for all: the offsets look like jitter
    flagged = lambda mon, fixes: np.mean([not mon.check(screen(f, 3.0, False)[0], CTX).trusted for f in fixes])
    assert flagged(after, [multi_fix(100.0 + 0.2 * k, rng) for k in range(400)]) < 0.01
    for system, *_ in SIGNALS:
        reflected = [multi_fix(100.0, rng, nlos=(system, 0)) for _ in range(200)]
        assert flagged(after, reflected) > 0.95, system
    assert flagged(before, [multi_fix(100.0, rng, nlos=("Galileo", 0)) for _ in range(200)]) < 0.5  # measured 7 %


def test_a_reflected_glonass_signal_is_still_caught():
    rng = np.random.default_rng(12)
    mon = monitors.create("cn0", nlos_bias_m=0)  # the C/N0 test alone
    for k in range(300):
        feed(mon, multi_fix(0.2 * k, rng))
    verdict = mon.check(screen(multi_fix(100.0, rng, nlos=("GLONASS", 2)), 3.0, False)[0], CTX)
    assert not verdict.trusted and "GLONASS 3 L1OF" in verdict.reason


def test_prior_offsets_stand_until_a_signal_is_learned():
    mon = monitors.create("cn0", min_samples_per_signal=10_000)  # never learned
    rng = np.random.default_rng(13)
    for k in range(300):
        feed(mon, multi_fix(0.2 * k, rng))
    assert mon.offsets()["GLONASS L1OF"] == -2.5 and mon.offsets()["Galileo E1-BC"] == 1.5


def test_a_receiver_profile_judges_from_the_first_fix():
    mon = monitors.create("cn0", profile_template=[HORIZON_DBHZ, ZENITH_DBHZ - HORIZON_DBHZ, JITTER_DB])
    rng = np.random.default_rng(14)
    el = np.array([15.0, 35.0, 50.0, 65.0, 80.0])
    snr = direct_cn0(el, rng)
    assert feed(mon, make_fix(0.0, el, snr)).trusted
    snr[3] -= NLOS_LOSS_DB
    verdict = feed(mon, make_fix(10.0, el, snr))
    assert not verdict.trusted and "PRN 4" in verdict.reason


# ------------------------------------------------------------------------- satellites whose direct signals differ

ZEUS = Path(__file__).parent / "data" / "nmea" / "gpsd" / "bundg_zeus_9.log"
"""A B&G Zeus2 9 chartplotter on a boat in open water on the IJsselmeer (gpsd's test log): GPS + GLONASS at 1 Hz."""


def zeus_observations():
    """The log's fixes as an estimator screens them (measured positions only)."""
    recording = nmea_log.read(ZEUS, nmea_log.Place((0.0, 0.0, 0.0), datetime(2018, 8, 20, tzinfo=UTC)))
    return [obs for obs in (screen(event.fix, 3.0, False)[0] for event in recording.events()) if obs is not None]


def test_a_real_boats_open_water_fixes_are_trusted():
    # its direct signals differ between satellites by up to 20 dB at one elevation (PRN 29 at 11 deg: 46 dB-Hz, PRN 8 at
    # 12 deg: 24-35) and each stays at its own level: before the spread between satellites was measured, 18 % were trusted
    obs = zeus_observations()
    assert len(obs) > 140
    online = monitors.create("cn0")
    verdicts = []
    for o in obs:
        verdicts.append(online.check(o, CTX))
        online.commit(o, verdicts[-1])
    assert sum(math.isfinite(v.statistic) for v in verdicts) > 120
    assert np.mean([v.trusted for v in verdicts]) >= 0.95
    learned = monitors.create("cn0", nlos_bias_m=0)  # the C/N0 test alone: the weak satellite below is flagged wherever it is
    for o in obs:
        learned.calibrate(o)
    assert np.mean([learned.check(o, CTX).trusted for o in obs]) >= 0.95
    # it still judges: a used satellite far below what this receiver's direct signals give is flagged and named
    expected, sigma = learned.template(74.0)
    assert 1.65 < sigma < 10.0  # wider than the jitter of one satellite (1.65 dB), the spread between them
    last = obs[-1]
    weak = tuple(
        s if s.prn != 16 or s.system != "GPS" else SatelliteReport(16, s.az_deg, s.el_deg, float(expected) - (learned.gate + 1) * sigma, True)
        for s in last.sats
    )
    verdict = learned.check(dataclasses.replace(last, sats=weak), CTX)
    assert not verdict.trusted and "PRN 16" in verdict.reason


def persistent_sky(rng, n: int, levels_db, nlos_from: int | None = None):
    """n epochs at 1 Hz of satellites that keep their number, elevation (drifting slowly) and their own C/N0 level
    (levels_db) about one template with 1 dB jitter; from epoch nlos_from, PRN 3 is received by reflection only."""
    el0 = np.linspace(8.0, 80.0, len(levels_db))
    out = []
    for k in range(n):
        el = el0 + 0.01 * k
        snr = direct_cn0(el, rng) + np.asarray(levels_db)
        if nlos_from is not None and k >= nlos_from:
            snr[2] -= NLOS_LOSS_DB
        out.append(make_fix(float(k), el, snr))
    return out


def test_satellites_at_their_own_levels_widen_sigma_to_their_spread():
    rng = np.random.default_rng(15)
    levels = rng.normal(0.0, 4.0, 12)  # persistent differences between satellites, 4 dB, as on a small boat
    mon = monitors.create("cn0")
    verdicts = [feed(mon, fix) for fix in persistent_sky(rng, 300, levels)]
    assert np.mean([v.trusted for v in verdicts]) > 0.99
    assert 3.0 < mon.template(30.0)[1] < 6.0
    bins_only = monitors.create("cn0", satellite_levels=False)
    assert np.mean([feed(bins_only, fix).trusted for fix in persistent_sky(np.random.default_rng(15), 300, levels)]) < 0.5


def test_a_sky_whose_satellites_share_one_level_is_judged_by_the_bins_alone():
    """Satellites that keep their identity but share the template (as the simulator's do): the same verdicts, to the
    last bit, as a monitor that never looks at satellites' levels, an NLOS satellite still flagged."""
    rng_a, rng_b = np.random.default_rng(16), np.random.default_rng(16)
    a, b = monitors.create("cn0"), monitors.create("cn0", satellite_levels=False)
    fa, fb = persistent_sky(rng_a, 300, np.zeros(10), nlos_from=200), persistent_sky(rng_b, 300, np.zeros(10), nlos_from=200)
    va, vb = [feed(a, f) for f in fa], [feed(b, f) for f in fb]
    assert [(v.trusted, v.reason) for v in va] == [(v.trusted, v.reason) for v in vb]
    assert all(x.statistic == y.statistic or (math.isnan(x.statistic) and math.isnan(y.statistic)) for x, y in zip(va, vb))
    assert not any(v.trusted for v in va[200:])


def test_the_simulators_verdicts_on_the_canal_are_the_bins_ones():
    """The library's canal_multipath stretch (the simulator's GPS L1 C/A receiver between walls that make a third of its
    fixes NLOS): the same verdicts, to the last bit, with and without the satellites' levels; NLOS fixes flagged."""
    run = assemble(scenarios.load("canal_multipath"))
    a, b = monitors.create("cn0"), monitors.create("cn0", satellite_levels=False)
    flagged = 0
    for t in run.receiver.epochs(run.t_end, run.t_start):
        obs = screen(run.receiver.fix(run.vessel_run.world, run.trajectory, float(t)), 3.0, False)[0]
        if obs is None:
            continue
        va, vb = a.check(obs, CTX), b.check(obs, CTX)
        a.commit(obs, va), b.commit(obs, vb)
        assert (va.trusted, va.reason) == (vb.trusted, vb.reason)
        assert va.statistic == vb.statistic or (math.isnan(va.statistic) and math.isnan(vb.statistic))
        flagged += not va.trusted
    assert flagged > 100 and a.between_satellites is not None
    spread, switch = a.between_satellites
    assert spread < switch


def crowned_fix(rng, t: float) -> tuple[GnssFix, int]:
    """A four-constellation fix as charles_river's banks give one (17 satellites: 9 GPS, 6 GLONASS, 1 Galileo, 1 BeiDou, their
    azimuths and elevations at 820 s of the fast stretch) whose GPS satellite at 14 deg crosses 5 m of a tree crown (sim.gnss's
    foliage_loss_db_per_m, Goldhirsh & Vogel: 1.3 dB/m): direct, no extra path; its index."""
    sky = [("GPS", 61, 63), ("GPS", 22, 127), ("GPS", 14, 185), ("GPS", 48, 56), ("GPS", 46, 279), ("GPS", 35, 50), ("GPS", 20, 265),
           ("GPS", 81, 337), ("GPS", 35, 208), ("GLONASS", 73, 264), ("GLONASS", 29, 326), ("GLONASS", 32, 171), ("GLONASS", 27, 43),
           ("GLONASS", 69, 345), ("GLONASS", 33, 251), ("Galileo", 26, 153), ("BeiDou", 54, 48)]  # fmt: skip
    offsets = {system: offset for system, _, offset, _ in SIGNALS} | {"BeiDou": -4.5}
    signals = {"GPS": "L1 C/A", "GLONASS": "L1OF", "Galileo": "E1-BC", "BeiDou": "B1I"}
    el = np.array([e for _, e, _ in sky], float)
    snr = np.array([direct_cn0(e, rng, offsets[system]) for (system, _, _), e in zip(sky, el)]).ravel()
    snr[2] -= 1.3 * 5.0
    sats = tuple(
        SatelliteReport(k + 1, float(a), float(e), float(c), True, system, signals[system]) for k, ((system, e, a), c) in enumerate(zip(sky, snr))
    )
    fix = GnssFix(stamp=t, lat=42.35, lon=-71.11, alt=0.0, enu=np.zeros(3), quality=1, num_sats=len(sats), hdop=0.7, vdop=1.2, pdop=1.4, sats=sats)
    return fix, 2


def test_a_direct_signal_through_a_tree_crown_does_not_refuse_the_fix():
    # C/N0 alone cannot tell a crown's attenuation from a reflection's loss (the satellite is 6.5 dB, > gate_sigma, down),
    # but a 14 deg satellite among 17 moves the fix 0.06 m per metre of range bias: even a reflection off a wall 25 m away
    # (2 x 25 m x cos 14 deg = 48.5 m) would move it 3.1 m. Before the suspects were weighed this refused 0.87 of
    # charles_river's [fast] fixes (all within 1.1 m)
    rng = np.random.default_rng(4)
    mon = monitors.create("cn0")
    for k in range(300):
        feed(mon, multi_fix(0.2 * k, rng))
    fix, crowned = crowned_fix(rng, 100.0)
    obs = screen(fix, 3.0, False)[0]
    deficits, sats, _, _ = mon.satellite_deficits(obs)
    assert deficits[crowned] > mon.gate and np.delete(deficits, crowned).max() < mon.gate  # the only suspect
    verdict = mon.check(obs, CTX)
    assert verdict.trusted and verdict.statistic < mon.gate and "PRN 3 " in verdict.reason and "at most 3.1 m" in verdict.reason
    assert not monitors.create("cn0", nlos_bias_m=0, profile_template=(35.0, 15.0, 1.0)).check(obs, CTX).trusted  # unweighed: refused


@settings(max_examples=60, deadline=None)
@given(suspect=st.integers(0, 16), bias_m=st.floats(5.0, 200.0), seed=st.integers(0, 2**16), vertical=st.booleans())
def test_a_suspect_refuses_the_fix_exactly_when_its_bias_through_the_geometry_exceeds_the_fault(suspect, bias_m, seed, vertical):
    """Analytic: the fix is refused iff the suspect's bias x its slope > fault_m, the slope being the horizontal shift of
    the elevation-weighted least-squares fix (the larger of one clock and one clock per system) computed here by perturbing
    the solution itself, the bias nlos_bias_m x cos(elevation) off a vertical wall (vertical_reflectors, the default) or
    nlos_bias_m at every elevation."""
    from fusion.monitors.satellite_geometry import horizontal_slopes

    rng = np.random.default_rng(seed)
    fix, _ = crowned_fix(rng, 100.0)
    el = np.array([s.el_deg for s in fix.sats])
    az = np.array([s.az_deg for s in fix.sats])
    systems = [s.system for s in fix.sats]
    # the shift of the weighted least-squares solution when satellite `suspect`'s range grows by 1 m, solved directly
    u = np.stack([np.cos(np.deg2rad(el)) * np.sin(np.deg2rad(az)), np.cos(np.deg2rad(el)) * np.cos(np.deg2rad(az)), np.sin(np.deg2rad(el))], 1)
    w = 1.0 / (1.0 + 1.0 / np.sin(np.deg2rad(el)) ** 2)  # sigma^2 = a^2 + (a / sin el)^2
    dy = np.zeros(len(el))
    dy[suspect] = 1.0
    shifts = []
    for clock in (np.ones((len(el), 1)), np.array([[float(s == c) for c in sorted(set(systems))] for s in systems])):  # one clock; one per system
        dx = np.linalg.lstsq(np.hstack([-u, clock]) * np.sqrt(w)[:, None], dy * np.sqrt(w), rcond=None)[0]
        shifts.append(float(np.hypot(dx[0], dx[1])))
    slope = max(shifts)
    assert horizontal_slopes(el, az, systems)[suspect] == pytest.approx(slope, rel=1e-9)
    snr = np.array([s.snr for s in fix.sats])
    snr[2] += 1.3 * 5.0  # the crowned one direct again
    snr[suspect] -= 12.0  # the suspect, clearly below the template
    sats = tuple(dataclasses.replace(s, snr=float(c)) for s, c in zip(fix.sats, snr))
    mon = monitors.create(
        "cn0",
        nlos_bias_m=bias_m,
        vertical_reflectors=vertical,
        profile_template=(35.0, 15.0, 1.0),
        offsets_db={"GPS L1 C/A": 0.0, "GLONASS L1OF": -3.0, "Galileo E1-BC": 2.0, "BeiDou B1I": -4.5},
    )
    verdict = mon.check(screen(dataclasses.replace(fix, sats=sats), 3.0, False)[0], CTX)
    shift = bias_m * (np.cos(np.deg2rad(el[suspect])) if vertical else 1.0) * slope
    if abs(shift - 5.0) > 1e-6:
        assert verdict.trusted == (shift <= 5.0), (shift, verdict.reason)


@settings(max_examples=200, deadline=None)
@given(
    rows=st.lists(
        st.lists(st.one_of(st.just(math.nan), st.floats(20.0, 55.0).map(lambda v: round(v, 1))), min_size=1, max_size=40), min_size=1, max_size=9
    ),
    q=st.tuples(st.floats(0.5, 0.99), st.floats(0.5, 0.99)),
)
def test_row_quantiles_are_numpys_nanquantile_bit_for_bit(rows, q):
    """The template fit's per-bin quantiles (a faster path) are exactly np.nanquantile's, NaN-padded bins included."""
    from fusion.monitors.cn0 import _row_quantiles

    width = max(len(r) for r in rows)
    values = np.array([r + [math.nan] * (width - len(r)) for r in rows])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy warns of an all-NaN row; ours gives its NaN silently
        expected = np.nanquantile(values, q, axis=1)
    assert _row_quantiles(values, q).tobytes() == expected.tobytes()


@settings(max_examples=200, deadline=None)
@given(
    values=st.lists(st.floats(-20.0, 20.0).map(lambda v: round(v, 2)), min_size=1, max_size=60),
    groups=st.integers(1, 400),
    q=st.floats(0.5, 0.99),
    seed=st.integers(0, 2**32 - 1),
)
def test_quantiles_by_group_sort_within_groups_as_lexsort_does(values, groups, q, seed):
    """The per-satellite levels' grouped sort (a faster path, up to hundreds of satellites) orders each group's values
    exactly as np.lexsort((values, group)), so the quantiles are the same bits; one signal's quantiles are np.quantile's
    numbers."""
    from fusion.monitors.cn0 import _quantile_by_group, _sorted_quantiles

    v = np.array(values)
    group = np.random.default_rng(seed).integers(0, groups, len(v))
    counts = np.bincount(group, minlength=groups)
    ordered = v[np.lexsort((v, group))]  # the reference: what _quantile_by_group sorted with before
    start = np.cumsum(counts) - counts
    position = start + np.maximum(counts - 1, 0) * q
    low = np.minimum(np.floor(position).astype(np.int64), len(ordered) - 1)
    high = np.minimum(low + 1, np.maximum(start + counts - 1, 0))
    expected = np.where(counts > 0, ordered[low] + (position - low) * (ordered[high] - ordered[low]), np.nan)
    assert _quantile_by_group(v, group, counts, q).tobytes() == expected.tobytes()
    qs = np.array([q, 0.9])
    # the same numbers; of a tie between -0.0 and 0.0 np.quantile's partition may pick either zero, as sorting may
    assert np.array_equal(_sorted_quantiles(np.sort(v), qs), np.quantile(v, qs))


def test_monitors_sharing_a_receivers_templates_judge_as_their_own_and_learn_each_fix_once():
    """The run's estimators judge one receiver's fixes, so their cn0 monitors share its template (fusion.monitors.create's
    templates): each fix is learned once, when the first of them judges the next one, and every verdict is the one a
    monitor learning alone gives, also for a combined monitor and with a share of NLOS reports in the learning."""
    templates = monitors.Cn0Templates()
    shared = [monitors.create("combined_cn0", templates=templates), monitors.create("cn0", templates=templates)]
    alone = [monitors.create("combined_cn0"), monitors.create("cn0")]
    assert shared[0].members[1].learned is shared[1].learned is templates.get(shared[1].params)
    assert monitors.create("cn0", templates=templates, gate_sigma=3.0).learned is not shared[1].learned  # other parameters
    learned, learn = shared[1].learned, shared[1].learned.learn
    calls = []
    shared[1].learned.learn = lambda obs: (calls.append(obs.stamp), learn(obs))[1]  # type: ignore[method-assign]
    epochs = clean_epochs(np.random.default_rng(3), 300, nlos_share=0.15)
    for t, el, snr in epochs:
        fix = make_fix(t, el, snr)
        assert [feed(m, fix) for m in shared] == [feed(m, fix) for m in alone]
    assert calls == [t for t, _, _ in epochs[:-1]]  # each fix once; the last is learned when the next one is judged
    assert shared[1].template(30.0) == alone[1].template(30.0) and shared[1].offsets() == alone[1].offsets()
    assert calls[-1] == epochs[-1][0] and learned.template(30.0) == alone[1].template(30.0)  # asked, it learns the last


def test_estimators_share_a_template_only_when_they_screen_the_receivers_fixes_alike():
    """A host that takes the receiver's dead-reckoned fixes (GGA 6) judges fixes the others never see, so it learns
    from its own stream; built-in hosts that screen alike share one template."""
    templates = monitors.Cn0Templates()

    def learned(**params):
        return fusion.create("ekf", templates=templates, **params).monitor.members[1].learned

    assert learned() is learned() is fusion.create("pf", templates=templates).monitor.members[1].learned
    assert learned(accept_dead_reckoning=True) is not learned()
    assert fusion.create("ekf").monitor.members[1].learned is not learned()  # without a registry: its own
