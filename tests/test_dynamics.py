"""The WAM-V 3-DoF model against its published parameters, and the driven trajectory the sensors see."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.driven_trajectory import DrivenTrajectory
from sim.dynamics import Manoeuvring, WamvDynamics
from sim.trajectory import TrajectoryConfig

VRX = WamvDynamics()


def settle(commands, seconds=120.0, current=(0.0, 0.0), state=None):
    model = Manoeuvring(VRX, current)
    x = np.zeros(6) if state is None else np.asarray(state, float)
    for _ in range(int(seconds / 0.05)):
        x = model.step(x, np.asarray(commands, float), 0.05)
    return x


def test_full_ahead_reaches_the_speed_where_vrx_damping_balances_500_newtons():
    # 2 x 250 N = 51.3 u + 72.4 u^2  ->  u = 2.3937 m/s (4.65 kn)
    u = (-51.3 + math.sqrt(51.3**2 + 4 * 72.4 * 500.0)) / (2 * 72.4)
    x = settle((1.0, 1.0))
    assert x[3] == pytest.approx(u, rel=1e-4)
    assert abs(x[4]) < 1e-9 and abs(x[5]) < 1e-9 and abs(x[2]) < 1e-9  # straight: no sway, no yaw
    assert VRX.steady_surge_mps(500.0) == pytest.approx(u, rel=1e-12)


def test_cruise_command_holds_the_field_study_speed():
    c = VRX.cruise_command(2.0)
    assert c == pytest.approx((51.3 * 2 + 72.4 * 4) / 500.0)
    assert settle((c, c))[3] == pytest.approx(2.0, rel=1e-4)


def test_equal_and_opposite_thrust_spins_in_place_at_the_yaw_damping_rate():
    # left full astern (-100 N), right +0.4 (100 N): no net force, moment 2 x 1.027135 x 100 N m, r = N / nR
    x = settle((-1.0, 0.4), seconds=60.0)
    assert x[5] == pytest.approx(2 * 1.027135 * 100.0 / 400.0, rel=1e-4)
    assert abs(x[3]) < 1e-6 and abs(x[4]) < 1e-6
    assert x[5] > 0  # more thrust on the right turns the bow left (counter-clockwise from above)


def test_differential_thrust_turns_on_a_steady_circle():
    x = settle((0.5, 1.0), seconds=200.0)
    radius = math.hypot(x[3], x[4]) / x[5]
    later = settle((0.5, 1.0), seconds=10.0, state=x)
    assert later[3:] == pytest.approx(x[3:], abs=1e-6)  # steady
    assert 2.0 < radius < 20.0 and x[4] < 0  # a real turn, the stern skids outward (sway to the right in a left turn)


def test_a_drifting_boat_moves_with_the_current():
    x = settle((0.0, 0.0), seconds=300.0, current=(0.3, -0.2))
    ground = np.array([math.cos(x[2]) * x[3] - math.sin(x[2]) * x[4], math.sin(x[2]) * x[3] + math.cos(x[2]) * x[4]])
    assert ground == pytest.approx([0.3, -0.2], abs=1e-4)


def test_the_driven_trajectory_keeps_the_poses_it_was_driven_through():
    traj = DrivenTrajectory(TrajectoryConfig(), VRX, (10.0, 5.0, 0.3, 2.0), t0=100.0)
    traj.drive((0.8, 0.8), 100.1)
    traj.drive((0.6, 0.9), 100.2)
    ts = np.array([100.0, 100.05, 100.1, 100.2])
    poses = traj.poses(ts)
    assert poses[0][:3, 3] == pytest.approx([10.0, 5.0, 0.0])
    assert math.atan2(poses[0][1, 0], poses[0][0, 0]) == pytest.approx(0.3)
    assert np.linalg.norm(poses[1][:2, 3] - poses[0][:2, 3]) == pytest.approx(0.1, rel=0.02)  # 2 m/s for 0.05 s
    assert traj.lidar_pose(100.2) == pytest.approx(poses[3] @ traj.mount)
    with pytest.raises(ValueError, match="outside the driven"):
        traj.pose(100.3)
    with pytest.raises(ValueError, match="commands"):
        traj.drive((math.nan, 0.0), 100.3)


def test_the_straight_course_is_stable_at_full_speed():
    # a yaw-rate kick at full speed dies out without any steering (no Munk-moment instability)
    x = settle((1.0, 1.0), seconds=60.0)
    x[5] = 0.2
    later = settle((1.0, 1.0), seconds=60.0, state=x)
    assert abs(later[5]) < 2e-3 and abs(later[4]) < 1e-2  # from 0.2 rad/s
