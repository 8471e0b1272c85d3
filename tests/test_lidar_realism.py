"""Realism on the charles_river route: points per revolution near structures and water returns,
against the field study (6,000-27,000 points per revolution near structures, almost none from water)."""

import numpy as np
import pytest

import worlds
from sim import HDL32E, Trajectory


@pytest.fixture(scope="module")
def route_scans():
    world = worlds.load("charles_river")
    traj = Trajectory(world)
    lidar = HDL32E()
    stamps = np.linspace(0.0, traj.duration - 1.0, 40)
    return world, [lidar.scan(world, traj, float(t)) for t in stamps]


def test_water_returns_are_a_tiny_share(route_scans):
    world, scans = route_scans
    labels = np.concatenate([s.points["label"] for s in scans])
    assert world.part_is_water[labels].mean() < 0.01


def test_near_structures_the_point_count_is_in_the_field_study_band(route_scans):
    world, scans = route_scans
    counts = np.array([len(s) for s in scans])
    structure = np.array([(~world.part_is_water[s.points["label"]]).sum() > 3000 for s in scans])
    assert structure.sum() >= 5
    in_band = (counts[structure] >= 6_000) & (counts[structure] <= 27_000)
    assert in_band.mean() >= 0.5
    assert counts.max() < 69_440  # never more than the rays of a revolution
