"""The real stack through a GPS blackout: worlds, sim.Trajectory, sim.HDL32E, sim.GnssReceiver, gicp
and the estimators, scored against the simulator's exact truth.

Under a charles_river bridge a GPS-only receiver coasts on its filter for 9 s and its dead-reckoned output
runs tens of metres off; in canal_lock the same happens at the lock's road bridge, between stretches
where the walls leave mostly reflected (NLOS) satellites. The ekf keeps the error to GPS's own
nominal level through the outage and after it, where gps_only (and in the canal hdop_switch) err
by metres.
"""

from __future__ import annotations

import numpy as np
import pytest
from stream_drive import drive

import fusion
import matcher
import sim
import worlds
from fusion.observation import POSITION_QUALITIES
from sim.gnss import GnssReceiver

NAMES = ("gps_only", "hdop_switch", "ekf")
GPS_ONLY = {"profile": "consumer", "constellations": ["GPS"]}
"""The receiver whose blackouts these tests are about: a GPS-only module without corrections. The default (four systems
with SBAS) keeps a fix under that deck but for 3.2 s (benchmarks/constellations.py compares the two)."""


def drive_stretch(world_name: str, t0: float, t1: float):
    world = worlds.load(world_name)
    trajectory = sim.Trajectory(world)
    estimators = {n: fusion.create(n, matcher="gicp") for n in NAMES}
    return drive(world, trajectory, sim.HDL32E(), GnssReceiver(**GPS_ONLY), {"gicp": matcher.create("gicp")}, estimators, t0, t1)


def outage(track) -> tuple[float, float]:
    """[start, end) of the stretch without a measured fix."""
    lost = track.fix_stamp[~np.isin(track.fix_quality, sorted(POSITION_QUALITIES))]
    assert len(lost), "the stretch has no outage"
    return float(lost.min()), float(lost.max()) + 0.2


def entry(track, name: str, t: float) -> float:
    """An estimate's error at the last scan before `t` (what an outage starting at t adds to)."""
    return float(track.error(name)[track.scan_stamp < t][-1])


def worst(track, name: str, t_from: float, t_to: float) -> float:
    in_span = (track.scan_stamp >= t_from) & (track.scan_stamp < t_to)
    return float(np.nanmax(track.error(name)[in_span]))


@pytest.fixture(scope="module")
def charles_bridge():
    return drive_stretch("charles_river", 815.0, 885.0)


@pytest.fixture(scope="module")
def canal():
    return drive_stretch("canal_lock", 120.0, 230.0)


@pytest.mark.slow  # the fast suite's harvard_beam_bridge runs the same stack through this outage, with its expectations checked against gps_only
def test_charles_river_bridge_outage(charles_bridge):
    a, b = outage(charles_bridge)
    assert 5.0 < b - a < 15.0
    ekf_entry, gps_entry = entry(charles_bridge, "ekf", a), entry(charles_bridge, "gps_only", a)
    ekf_added = worst(charles_bridge, "ekf", a, b + 20.0) - ekf_entry
    gps_added = worst(charles_bridge, "gps_only", a, b + 20.0) - gps_entry
    assert gps_added > 5.0, "the receiver's coasted output runs off under the deck"
    assert ekf_added < 1.5 and ekf_added < 0.25 * gps_added
    assert worst(charles_bridge, "ekf", a - 20.0, a) < 1.5 * worst(charles_bridge, "gps_only", a - 20.0, a)  # GPS's own level before it


@pytest.mark.slow  # the fast suite's canal_multipath and steer_canal_multipath cover the NLOS canyon with the same stack
def test_canal_lock_outage_between_nlos_stretches(canal):
    a, b = outage(canal)
    ekf = worst(canal, "ekf", a, b + 20.0)
    assert worst(canal, "gps_only", a, b + 20.0) > 10.0
    assert worst(canal, "hdop_switch", a, b + 20.0) > 8.0
    assert ekf < 6.0
    # before it, the walls make the fixes err by metres (NLOS) while the ekf refuses them
    before = (canal.fix_stamp >= a - 50.0) & (canal.fix_stamp < a) & np.isin(canal.fix_quality, sorted(POSITION_QUALITIES))
    assert np.max(canal.fix_error[before]) > 10.0
    assert worst(canal, "ekf", a - 50.0, a) < 6.0
    assert not canal.trusted["ekf"][before & (canal.fix_error > 10.0)].any()
