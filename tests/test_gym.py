"""RiverNav-v0: registration, Gymnasium's own checker, seeded reproducibility, the vector API, what the
agent sees (never the truth) and the rendered frame."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import scenarios.gym
from scenarios.gym.observation import range_image
from sim.scan import POINT_DTYPE

SCENARIO = "open_river"
SHORT = ["stretch={start_m=100.0, end_m=110.0}"]


def make(**kw):
    return gymnasium.make(scenarios.gym.ENV_ID, scenario=SCENARIO, set=SHORT, azimuth_bins=36, **kw)


def test_gymnasiums_env_checker_passes():
    env = make(render_mode="rgb_array")
    check_env(env.unwrapped)
    env.close()


def test_the_same_seed_and_actions_reproduce_an_episode_exactly():
    def episode(seed):
        env = make()
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for k in range(12):
            obs, reward, *_ = env.step(np.array([0.8, 0.75 + 0.01 * k], np.float32))
            out.append((obs, reward))
        env.close()
        return out

    a, b, c = episode(5), episode(5), episode(6)
    assert identical(a, b)  # every element of every array, not a repr that numpy summarises past 1000 elements
    assert not identical(a, c)


def identical(a, b) -> bool:
    """Exact equality of nested observations (dicts, tuples, lists, arrays, floats), arrays compared element by element."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(identical(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return isinstance(b, (list, tuple)) and len(a) == len(b) and all(identical(x, y) for x, y in zip(a, b))
    a_arr, b_arr = np.asarray(a), np.asarray(b)
    return a_arr.shape == b_arr.shape and a_arr.dtype == b_arr.dtype and bool(np.array_equal(a_arr, b_arr, equal_nan=True))


def test_the_observation_is_what_the_boat_knows_and_info_the_truth():
    env = make()
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    for _ in range(15):
        obs, reward, terminated, truncated, info = env.step(np.array([0.78, 0.78], np.float32))
    assert obs["lidar"].shape == (32, 36) and obs["gps_quality"] == 2 and obs["estimate_valid"] in (0, 1)
    assert {"true_pose", "true_cross_track_m", "clearance_m"} <= set(info)
    assert not set(obs) & {"true_pose", "clearance_m"}
    # straight ahead at cruise on open water: about 0.2 m gained per step, reward ~= progress
    assert info["true_station_m"] == pytest.approx(100.0 + 15 * 0.2, abs=0.5)
    assert 0.1 < reward < 0.3


def test_the_episode_terminates_at_the_end_of_the_stretch_and_only_then_has_an_outcome():
    env = make()
    _, info = env.reset(seed=0)
    outcomes = [info.get("outcome")]
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(np.array([1.0, 1.0], np.float32))
        outcomes.append(info.get("outcome"))
    assert terminated and not truncated and info["outcome"] == "completed" and 30 < len(outcomes) - 1 < 60  # 10 m at up to 2.4 m/s
    assert outcomes[:-1] == [None] * (len(outcomes) - 1)  # mid-episode no outcome (it used to say "interrupted")


def test_an_episode_that_runs_out_of_time_is_truncated_with_that_outcome_at_its_last_step_only():
    env = make()
    env.reset(seed=0)
    infos = []
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))  # thrusters off: the boat drifts to a stop
        infos.append(info)
    assert truncated and not terminated and infos[-1]["outcome"] == "time_limit"
    assert not any("outcome" in i for i in infos[:-1])
    env.close()


def test_sync_and_async_vector_envs_step_in_lockstep():
    fns = [lambda: make() for _ in range(2)]
    for vec in (gymnasium.vector.SyncVectorEnv(fns), gymnasium.vector.AsyncVectorEnv(fns)):
        obs, _ = vec.reset(seed=[3, 3])
        for _ in range(3):
            obs, rewards, *_ = vec.step(np.full((2, 2), 0.8, np.float32))
        assert obs["lidar"].shape == (2, 32, 36)
        assert rewards[0] == rewards[1]  # same seed, same actions
        vec.close()


def test_render_draws_a_top_view_frame():
    env = make(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([0.8, 0.8], np.float32))
    frame = env.render()
    assert frame.shape == (480, 480, 3) and frame.dtype == np.uint8 and frame.std() > 5
    env.close()


def test_the_range_image_holds_the_nearest_return_per_beam_and_bin():
    pts = np.zeros(3, dtype=POINT_DTYPE)
    pts["x"], pts["y"], pts["ring"] = [10.0, 5.0, -7.0], [0.0, 0.0, 0.0], [15, 15, 0]
    image = range_image(pts, 4, 100.0)
    assert image.shape == (32, 4)
    # laser 15 is level (0 deg): row of the 0-degree beam; ahead (azimuth 0) is bin 2 of 4, behind bin 0
    row15, row0 = scenarios.gym.observation.RING_ROWS[15], scenarios.gym.observation.RING_ROWS[0]
    assert image[row15, 2] == pytest.approx(5.0) and image[row0, 3] == pytest.approx(7.0)  # straight behind: +180 deg, the last bin
    assert row0 == 31 and np.count_nonzero(image) == 2


def test_bad_arguments_are_one_line_errors():
    with pytest.raises(ValueError, match="estimator 'kalman'"):
        gymnasium.make(scenarios.gym.ENV_ID, scenario=SCENARIO, estimator="kalman")
    env = make()
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.zeros(2))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.unwrapped.step(np.array([np.nan, 0.0]))


def test_an_estimator_fed_the_imu_and_compass_gets_them_in_the_env_as_in_a_run():
    fed = 'estimators=[{id="ekf", kind="ekf", sensors=["gnss", "odometry", "imu", "compass"]}]'
    env = gymnasium.make(scenarios.gym.ENV_ID, scenario=SCENARIO, set=[*SHORT, fed, "expect=[]"], azimuth_bins=36, estimator="ekf")
    env.reset(seed=3)
    for _ in range(5):
        env.step(np.array([0.78, 0.78], np.float32))
    episode = env.unwrapped._episode
    headings = episode.feed.recorder.heading_rows["t"].array()
    assert len(headings) >= 5 * 0.1 * episode.run.compass.config.rate_hz - 1  # every compass output of the 5 steps, once
    assert np.all(np.diff(headings) > 0) and headings[-1] <= episode.sensed_until
    assert "ekf" not in episode.feed.dead
    env.close()
