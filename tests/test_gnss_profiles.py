"""Receiver profiles: each reproduces its datasheet's open-sky figures; the RTK profile fixes, loses lock under a
bridge and re-fixes after the convergence time; profiles are defaults a written field overrides; GGA carries
the quality, age of corrections and station as pynmea2 reads them."""

from datetime import timedelta

import gnss_worlds as gw
import numpy as np
import pynmea2
import pytest
from pydantic import ValidationError
from typer.testing import CliRunner

import scenarios
from scenarios.cli import app
from sim import GnssReceiver
from sim.gnss import GnssConfig
from sim.gnss_profiles import PROFILES
from sim.pseudorange import PseudorangeNoise
from sim.receiver_filter import FilterConfig
from sim.rtk import RTK_FIXED, RTK_FLOAT, RtkConfig, RtkLock

TOLERANCE = 0.15
"""The measured open-sky figures must be within 15% of the profile's datasheet figures."""


def open_sky_errors(profile: str, records: int = 24, seconds: float = 600.0, constellations: tuple[str, ...] | None = None) -> np.ndarray:
    """Horizontal errors of a static receiver in open water, 1 Hz, `records` records spread over the ephemeris file's
    span (satellite geometry and the slow errors vary; datasheets quote 24 h records, the shipped broadcast ephemeris
    covers 7.5 h), the first minute of each dropped."""
    world, still = gw.open_water(), gw.Static()
    sky = GnssReceiver().constellation
    step = (sky.end_utc - sky.start_utc - timedelta(seconds=seconds)) / records
    errors = []
    for h in range(records):
        systems = {} if constellations is None else {"constellations": list(constellations)}
        rx = GnssReceiver(rate_hz=1.0, seed=h, profile=profile, epoch_utc=sky.start_utc + h * step, **systems)
        for t in rx.epochs(seconds):
            fix = rx.fix(world, still, t)
            if t >= 60.0:
                assert fix.quality in (1, 2, 4)
                errors.append(np.hypot(*fix.truth.error[:2]))
    return np.asarray(errors)


@pytest.mark.parametrize("profile", sorted(set(PROFILES) - {"sbas_gps"}))  # sbas_gps is sbas with GPS: see the next test
def test_open_sky_cep50_is_the_datasheet_figure_with_gps_as_the_datasheet_states_it(profile):
    # The datasheets state GPS figures (NEO-M8N 2.5 m CEP GPS, the V102 a GPS L1 receiver). Their p95 is not checked:
    # the profiles derive it as 2.079 CEP50 (a circular normal error of constant geometry), but the real sky's GPS
    # geometry over the 7.5 h the broadcast ephemeris covers varies, and the measured p95 / CEP50 is 2.8 (consumer).
    errors = open_sky_errors(profile, constellations=("GPS",))
    assert np.median(errors) == pytest.approx(PROFILES[profile].cep50_m, rel=TOLERANCE)


def test_sbas_gps_profile_is_sbas_tracking_gps_alone():
    # the field study's receiver (riverbench study --setup field): sbas's every field, GPS its only system, its carrier
    # smoothing restarting at reacquisition (the raw code's 0.6 m white noise, the consumer's; off in the library's sbas)
    gps = GnssConfig(profile="sbas_gps")
    assert gps.constellations == ("GPS",) and gps.noise.restart_white_zenith_m == PseudorangeNoise().white_zenith_m == 0.6
    sbas = GnssConfig(profile="sbas", constellations=("GPS",), noise={"restart_white_zenith_m": 0.6})
    assert gps.model_dump(exclude={"profile"}) == sbas.model_dump(exclude={"profile"})
    assert GnssConfig(profile="sbas").noise.restart_white_zenith_m is None
    assert PROFILES["sbas_gps"].cep50_m == PROFILES["sbas"].cep50_m


def test_default_receiver_is_sub_metre_in_open_sky_as_the_field_study_found():
    # the default: the sbas profile tracking GPS, GLONASS, Galileo and BeiDou (measured p95 0.59 m; GPS alone 1.16 m)
    assert GnssConfig().profile == "sbas" and np.percentile(open_sky_errors("sbas"), 95) < 1.0


def test_rtk_profile_figures_follow_the_baseline():
    assert PROFILES["rtk"].cep50_m == pytest.approx(0.01 + 1e-6 * RtkConfig().baseline_m)
    long_base = GnssConfig(profile="rtk", rtk={"baseline_m": 20_000.0}).rtk
    assert long_base.fixed_sigma_m == pytest.approx(0.03 / np.sqrt(2.0 * np.log(2.0)))


def test_a_profile_fills_only_the_fields_not_written():
    sbas = PROFILES["sbas"].defaults
    config = GnssConfig(noise={"white_zenith_m": 0.5})
    assert config.profile == "sbas"
    assert config.noise.white_zenith_m == 0.5  # written: wins
    assert config.noise.correlated_zenith_m == sbas["noise"]["correlated_zenith_m"]  # not written: the profile's
    assert config.filter.fix_sigma_m == sbas["filter"]["fix_sigma_m"]
    assert config.corrections.kind == "sbas"
    # a model instance counts the fields its author set, no more
    instance = GnssConfig(profile="rtk", noise=PseudorangeNoise(white_zenith_m=0.5), corrections={"station_id": 7})
    assert instance.noise.white_zenith_m == 0.5 and instance.noise.correlated_zenith_m == PROFILES["rtk"].defaults["noise"]["correlated_zenith_m"]
    assert instance.corrections.kind == "rtk" and instance.corrections.station_id == 7


def test_consumer_profile_is_the_fields_own_defaults():
    config = GnssConfig(profile="consumer")
    assert config.noise == PseudorangeNoise() and config.filter == FilterConfig() and config.corrections.kind == "none"


@pytest.mark.parametrize("profile", sorted(PROFILES))
def test_a_resolved_config_validates_to_itself(profile):
    config = GnssConfig(profile=profile, rtk={"baseline_m": 1000.0})
    assert GnssConfig.model_validate(config.model_dump()) == config
    assert GnssConfig.model_validate(config.model_dump(mode="json")) == config


def test_scenario_gnss_table_profile_and_override_and_resolved_scenario_reproduces(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('world = "open_river"\n[gnss]\nprofile = "rtk"\n[gnss.noise]\nwhite_zenith_m = 0.4\n')
    scenario = scenarios.load(path)
    assert scenario.gnss.profile == "rtk" and scenario.gnss.corrections.kind == "rtk"
    assert scenario.gnss.noise.white_zenith_m == 0.4
    assert scenario.gnss.noise.correlated_zenith_m == PROFILES["rtk"].defaults["noise"]["correlated_zenith_m"]
    import tomli_w

    again = tmp_path / "resolved.toml"
    again.write_text(tomli_w.dumps(scenario.resolved()))
    assert scenarios.load(again).gnss == scenario.gnss
    switched = scenarios.load(path, set=["gnss.profile=consumer"])
    assert switched.gnss.corrections.kind == "none" and switched.gnss.noise.white_zenith_m == 0.4


def test_unknown_profile_names_the_key_and_the_known_profiles():
    with pytest.raises(ValidationError) as info:
        GnssConfig(profile="garmin")
    error = info.value.errors()[0]
    assert error["loc"] == ("profile",) and all(name in error["msg"] for name in PROFILES)


def test_cli_unknown_profile_is_one_line_and_exit_2(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", "open_river", "--set", "gnss.profile=garmin", "--out", str(out), "--quiet"])
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert "gnss.profile" in lines[0] and all(name in lines[0] for name in PROFILES) and "Traceback" not in result.output
    assert not out.exists()


def test_rtk_lock_fixes_after_convergence_and_a_cycle_slip_restarts_it():
    config = RtkConfig(convergence_s=10.0, min_fix_sats=5)
    lock = RtkLock.start(config)
    five = [1, 2, 3, 4, 5]
    assert lock.update(0.0, five, False) == (RTK_FLOAT, 0.0)
    assert lock.update(9.0, five, False) == (RTK_FLOAT, 9.0)
    assert lock.update(10.0, five, False) == (RTK_FIXED, 10.0)
    assert lock.update(11.0, five, True)[0] == RTK_FLOAT  # a reflected-only satellite tracked: no validated fix
    assert lock.update(12.0, [1, 2, 3, 4, 5, 6], False) == (RTK_FIXED, 12.0)  # a new satellite does not break it
    assert lock.update(13.0, [1, 2, 3, 4, 6], False) == (RTK_FLOAT, 1.0)  # satellite 5 lost: 6 has held lock 1 s
    assert lock.update(14.0, [1, 2, 3, 4, 5, 6], False) == (RTK_FLOAT, 2.0)  # 5 back with a new ambiguity: 6 (2 s) is fifth
    assert lock.update(22.0, [1, 2, 3, 4, 5, 6], False) == (RTK_FIXED, 10.0)  # 6 has held lock 10 s
    assert lock.update(23.0, [1, 2, 3], False) == (RTK_FLOAT, 0.0)  # too few satellites
    assert lock.float_weight(0.0) == 1.0 and lock.float_weight(10.0) == pytest.approx(np.exp(-3.0))


def test_rtk_fixes_in_open_sky_after_its_convergence_time_then_holds_it():
    rx = GnssReceiver(rate_hz=5.0, seed=3, profile="rtk")
    world, still = gw.open_water(), gw.Static()
    fixes = [rx.fix(world, still, t) for t in rx.epochs(60.0)]
    quality = np.array([f.quality for f in fixes])
    stamps = np.array([f.stamp for f in fixes])
    convergence = rx.config.rtk.convergence_s
    assert (quality[stamps < convergence - 1e-9] == RTK_FLOAT).all()
    assert (quality[stamps >= convergence - 1e-9] == RTK_FIXED).all()
    fixed_error = np.array([np.hypot(*f.truth.error[:2]) for f in fixes if f.quality == RTK_FIXED])
    assert fixed_error.max() < 0.1  # centimetres
    assert all(f.num_sats >= rx.config.rtk.min_fix_sats for f in fixes)


def test_rtk_loses_its_fix_under_a_bridge_then_floats_then_fixes_after_the_convergence_time():
    rx = GnssReceiver(rate_hz=5.0, seed=1, profile="rtk")
    world, boat = gw.bridge(), gw.Straight(speed=2.0, x0=40.0)  # deck at x 100..160: under it from t=30 s to t=60 s
    fixes = [rx.fix(world, boat, t) for t in rx.epochs(110.0)]
    stamps = np.array([f.stamp for f in fixes])
    quality = np.array([f.quality for f in fixes])
    error = np.array([np.hypot(*f.truth.error[:2]) if f.quality else np.nan for f in fixes])
    # satellites tracked (C/N0 reported) by their direct signal: the ones holding carrier lock
    direct = np.array([sum(s.los for s in f.truth.sats if any(r.prn == s.prn and r.snr > 0 for r in f.sats)) for f in fixes])
    before = stamps < 25.0
    assert (quality[before & (stamps >= 10.0)] == RTK_FIXED).all() and np.nanmax(error[before & (stamps >= 10.0)]) < 0.1
    under = (stamps > 32.0) & (stamps < 58.0)
    assert not np.isin(quality[under], (RTK_FIXED, RTK_FLOAT)).any()  # no satellites: dead reckoning, then no fix
    after = stamps >= 45.0  # mid-deck: every satellite blocked
    first_fixed = stamps[after & (quality == RTK_FIXED)][0]
    back = stamps[after & (direct >= rx.config.rtk.min_fix_sats)][0]  # enough of them again
    convergence = rx.config.rtk.convergence_s
    assert first_fixed - back == pytest.approx(convergence, abs=1.0 / rx.rate_hz + 1e-9)
    floating = after & (stamps >= back) & (stamps < first_fixed)
    assert (quality[floating] == RTK_FLOAT).all() and floating.sum() >= convergence * rx.rate_hz - 1
    late_float = floating & (stamps >= back + convergence / 2)
    assert np.nanmax(error[late_float]) < 1.0  # decimetres once converging, not the code solution's metres
    assert np.nanmax(error[after & (stamps >= first_fixed)]) < 0.1


def test_gga_carries_quality_age_and_station_as_pynmea2_reads_them():
    world, still = gw.open_water(), gw.Static()
    seen = {}
    for profile, station in (("rtk", "0000"), ("sbas", "0133"), ("consumer", "")):
        rx = GnssReceiver(rate_hz=5.0, seed=2, profile=profile)
        for t in rx.epochs(14.0):
            fix = rx.fix(world, still, t)
            gga = pynmea2.parse(fix.nmea()[0])
            assert gga.gps_qual == fix.quality
            seen.setdefault(profile, set()).add(gga.gps_qual)
            if profile == "consumer":
                assert gga.age_gps_data == "" and gga.ref_station_id == ""
                continue
            assert float(gga.age_gps_data) == pytest.approx(fix.correction_age_s, abs=0.05)
            assert 0.0 <= fix.correction_age_s <= rx.config.corrections.latency_s + rx.config.corrections.interval_s
            assert gga.ref_station_id == station
    assert seen == {"rtk": {RTK_FLOAT, RTK_FIXED}, "sbas": {2}, "consumer": {1}}


def test_every_profile_name_has_a_profile():
    from typing import get_args

    from sim.gnss_profiles import ProfileName

    assert set(get_args(ProfileName)) == set(PROFILES)
    assert all(p.receiver and p.figures and p.why for p in PROFILES.values())
