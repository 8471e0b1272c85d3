"""Start-up alignment (fusion.bootstrap): the heading it starts a filter on is as good as the uncertainty it claims.

A boat under way along +x (true yaw 0) in open water, the bench's receiver model with its time-correlated errors,
and either exact odometry (the odometry track's fit) or none (the GPS course). The first accepted alignment of
each start must lie within two of its own claimed heading sigmas: a filter started on a heading it trusts more than
it should never recovers it without GPS (docs/models.md, the start-up paragraph).
"""

from __future__ import annotations

from datetime import timedelta

import gnss_worlds as gw
import numpy as np
import pytest

from fusion.bootstrap import Bootstrap
from fusion.ekf import EkfParams
from fusion.observation import screen
from fusion.odometry import OdometryTrack
from sim import GnssReceiver

STARTS = 12
"""Starts per case, spread over the ephemeris file's span (satellite geometry and the receiver's slow errors vary)."""


def first_alignments(with_odometry: bool) -> tuple[np.ndarray, np.ndarray]:
    """Yaw error (deg) and claimed yaw sigma (deg) of each start's first accepted alignment."""
    p = EkfParams()
    world, boat = gw.open_water(), gw.Straight(speed=2.0)
    sky = GnssReceiver().constellation
    errors, sigmas = [], []
    for k in range(STARTS):
        epoch = sky.start_utc + (sky.end_utc - sky.start_utc - timedelta(seconds=300)) * (k / STARTS)
        receiver = GnssReceiver(seed=k, epoch_utc=epoch)
        bootstrap = Bootstrap(p.init_baseline_m, p.init_min_fixes, p.init_max_hdop, np.zeros(2), p.init_max_yaw_sd_deg)
        odometry, next_scan = OdometryTrack(), 0.0
        for t in receiver.epochs(200.0):
            while with_odometry and next_scan <= t:  # exact 10 Hz steps of a boat at 2 m/s
                odometry.add(next_scan, np.array([0.2, 0.0, 0.0]), np.diag([1e-6, 1e-6, 1e-8]))
                next_scan = round(next_scan + 0.1, 9)
            obs, _ = screen(receiver.fix(world, boat, t), p.uere_m, False)
            if obs is None or t < 20.0:  # a boat already under way: the receiver's own filter has settled
                continue
            bootstrap.add(obs, odometry)
            alignment = bootstrap.alignment(obs.stamp)
            if alignment is not None:
                errors.append((np.degrees(alignment.pose[2]) + 180.0) % 360.0 - 180.0)
                sigmas.append(np.degrees(np.sqrt(alignment.cov[2, 2])))
                break
    return np.array(errors), np.array(sigmas)


@pytest.mark.parametrize("with_odometry", [True, False], ids=["odometry-fit", "gps-course"])
def test_the_start_heading_lies_within_two_of_its_claimed_sigmas_in_open_water(with_odometry):
    errors, sigmas = first_alignments(with_odometry)
    assert len(errors) == STARTS  # every start aligned within the 200 s
    assert np.all(sigmas <= EkfParams().init_max_yaw_sd_deg + 1e-9)
    z = errors / sigmas
    assert np.all(np.abs(z) <= 2.0), f"yaw errors {errors.round(2)} deg against claimed sigmas {sigmas.round(2)} deg"
    assert np.sqrt(np.mean(z**2)) <= 1.0
