"""The IMU and compass in and out of bags: exported as xsens_mti_driver publishes them (checked against its
imupublisher.h / magneticfieldpublisher.h and sensor_msgs' documented conventions, computed here from the
datasheet figures, not from riverbench's code), replayed into the estimators fed the IMU with the same estimates
as the run, and a real ROS 1 bag's Imu (robot_localization's test1.bag, a Husky) read exactly as rosbags reads it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer
from typer.testing import CliRunner

import scenarios
from scenarios.cli import app
from scenarios.export import export
from scenarios.export.frames import open_stream
from scenarios.export.ros_messages import typestore
from scenarios.pipeline import files
from scenarios.pipeline.inertial import ImuEvent
from scenarios.replay import bag as replay_bag
from scenarios.replay import replay
from scenarios.replay.recording import Place

REAL_BAG = Path(__file__).parent / "data" / "bag" / "robot_localization_test1.bag"
STRETCH = "stretch={start_m = 350.0, end_m = 353.0}"  # canal_multipath: 1.5 s, 15 scans
FED = '["gnss", "odometry", "imu"]'
DEG = math.pi / 180.0
MTI630_GYRO = 0.007 * DEG  # rad/s/sqrt(Hz), MTi 600-series datasheet
MTI630_ACCEL = 60e-6 * 9.80665  # m/s^2/sqrt(Hz)
IMU_RATE = 100.0  # sim.imu.ImuConfig default


def overrides(sensors: str = FED, lever: str = "[0.5, -0.2, 1.0]") -> list[str]:
    """The ekf fed the IMU (mounted off base_link's origin), started on the true start pose so it estimates from the first scan."""
    info, frames = open_stream(scenarios.load("canal_multipath", set=[STRETCH]))
    pose = next(iter(frames)).base_pose
    start = f"[{pose[0, 3]:.4f}, {pose[1, 3]:.4f}, {math.degrees(math.atan2(pose[1, 0], pose[0, 0])):.4f}]"
    return [STRETCH, f"estimators.ekf.sensors={sensors}", f"estimators.ekf.params.initial_pose={start}", f"imu.lever_m={lever}"]


def messages(bag: Path, topic: str) -> list:
    """Every message on `topic`, read by rosbags' AnyReader."""
    with AnyReader([bag], default_typestore=typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections)]


def vec(v) -> list[float]:
    return [v.x, v.y, v.z]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A run with an IMU-fed ekf and a compass, its rosbag2 export, and the simulated frames."""
    root = tmp_path_factory.mktemp("imuio")
    sets = overrides('["gnss", "odometry", "imu", "compass"]')
    info, frames = open_stream(scenarios.load("canal_multipath", set=sets))
    return {"bag": export("canal_multipath", "rosbag2", root / "bag", set=sets).out, "info": info, "frames": list(frames), "root": root}


def test_imu_data_is_what_xsens_mti_driver_publishes(exported):
    imu = messages(exported["bag"], "/imu/data")
    samples = [b for f in exported["frames"] for b in f.imu]
    gyro, accel = np.concatenate([b.gyro for b in samples]), np.concatenate([b.accel for b in samples])
    assert len(imu) == len(gyro) >= 140
    assert {m.header.frame_id for m in imu} == {"imu_link"}  # xsens_mti_node.yaml's default frame_id
    for m in imu:
        assert m.orientation_covariance[0] == -1  # imupublisher.h: "mark as not available"; sensor_msgs/Imu: no orientation
        # diagonal variances of the datasheet density at the output rate (Kalibr: sigma_d = sigma / sqrt(dt))
        np.testing.assert_allclose(m.angular_velocity_covariance, np.diag([MTI630_GYRO**2 * IMU_RATE] * 3).ravel(), rtol=1e-12)
        np.testing.assert_allclose(m.linear_acceleration_covariance, np.diag([MTI630_ACCEL**2 * IMU_RATE] * 3).ravel(), rtol=1e-12)
    np.testing.assert_array_equal([vec(m.angular_velocity) for m in imu], gyro)
    np.testing.assert_array_equal([vec(m.linear_acceleration) for m in imu], accel)
    assert np.mean([m.linear_acceleration.z for m in imu]) == pytest.approx(9.80, abs=0.05)  # specific force: +g up
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in imu])
    assert np.all(np.diff(stamps) == 10_000_000)  # 100 Hz on the header clock


def test_the_mount_and_the_magnetometer(exported):
    (static,) = messages(exported["bag"], "/tf_static")
    mounts = {t.child_frame_id: t for t in static.transforms}
    assert set(mounts) == {"velodyne", "gps", "imu_link"} and mounts["imu_link"].header.frame_id == "base_link"
    assert vec(mounts["imu_link"].transform.translation) == [0.5, -0.2, 1.0]
    q = mounts["imu_link"].transform.rotation
    assert [q.x, q.y, q.z, q.w] == [0.0, 0.0, 0.0, 1.0]
    mag = messages(exported["bag"], "/imu/mag")
    headings = [h for f in exported["frames"] for h in f.headings]
    assert len(mag) == len(headings) >= 14 and {m.header.frame_id for m in mag} == {"imu_link"}
    np.testing.assert_allclose([vec(m.magnetic_field) for m in mag], [h.field_ut * 1e-6 for h in headings], rtol=1e-15)
    assert 20e-6 < np.linalg.norm(vec(mag[0].magnetic_field)) < 80e-6  # tesla: the Earth's field is 25-65 uT
    np.testing.assert_allclose(mag[0].magnetic_field_covariance, np.diag([(0.05e-6) ** 2] * 3).ravel(), rtol=1e-12)  # 0.5 mG RMS
    # the unit's orientation as xsens_mti_driver's /filter/quaternion: ENU, yaw the heading (true), with its roll and pitch
    att = messages(exported["bag"], "/filter/quaternion")
    assert len(att) == len(headings) and {a.header.frame_id for a in att} == {"imu_link"}
    assert [a.header.stamp for a in att] == [m.header.stamp for m in mag]
    q = np.array([[a.quaternion.w, a.quaternion.x, a.quaternion.y, a.quaternion.z] for a in att])
    w, x, y, z = q.T
    np.testing.assert_allclose(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)), [h.yaw for h in headings], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.arcsin(2 * (w * y - z * x)), [h.pitch for h in headings], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)), [h.roll for h in headings], rtol=0, atol=1e-12)
    assert 0 < np.abs([h.roll for h in headings]).max() < 0.1  # the unit's own tilt estimate: truth plus its 0.2 deg error


def test_a_default_export_has_no_inertial_topics(tmp_path):
    bag = export("canal_multipath", "rosbag2", tmp_path / "bag", set=[STRETCH]).out
    with AnyReader([bag]) as reader:
        assert not {"/imu/data", "/imu/mag"} & set(reader.topics)


def test_an_imu_fed_ekf_replays_its_run(tmp_path):
    """Run, export the run, replay the bag: the IMU-fed ekf's estimates are the run's to the TUM file's precision."""
    scenario = scenarios.load("canal_multipath", set=overrides(lever="[0.0, 0.0, 0.0]"))
    run = scenarios.run(scenario, tmp_path / "run", workers=1, report=False)
    export(run.out_dir, "rosbag2", tmp_path / "bag")
    replayed = replay(tmp_path / "bag", scenario, tmp_path / "replay", workers=1, report=False)
    assert replayed.metrics["run"]["recording"]["imu"] == "/imu/data (frame imu_link, mount from /tf_static)"
    want, got = files.read_tum(run.out_dir / "ekf.tum"), files.read_tum(replayed.out_dir / "ekf.tum")
    assert len(want) >= 14 and got.shape == want.shape
    np.testing.assert_array_equal(got[:, 0], want[:, 0])
    np.testing.assert_allclose(got[:, 1:], want[:, 1:], rtol=0, atol=1e-6)
    # without the IMU the ekf's yaw differs: the replay did feed it
    plain = scenarios.load("canal_multipath", set=overrides(sensors='["gnss", "odometry"]', lever="[0.0, 0.0, 0.0]"))
    without = replay(tmp_path / "bag", plain, tmp_path / "replay_plain", workers=1, report=False)
    assert "imu" not in without.metrics["run"]["recording"]
    assert np.abs(files.read_tum(without.out_dir / "ekf.tum")[:, 4:] - want[:, 4:]).max() > 1e-6


def test_a_compass_fed_ekf_replays_its_run(tmp_path):
    """Run, export, replay with the ekf fed the IMU and the compass: the compass comes back from /filter/quaternion and
    /imu/mag, and the estimates are the run's to the TUM file's precision."""
    fed = '["gnss", "odometry", "imu", "compass"]'
    scenario = scenarios.load("canal_multipath", set=overrides(sensors=fed, lever="[0.0, 0.0, 0.0]"))
    run = scenarios.run(scenario, tmp_path / "run", workers=1, report=False)
    export(run.out_dir, "rosbag2", tmp_path / "bag")
    replayed = replay(tmp_path / "bag", scenario, tmp_path / "replay", workers=1, report=False)
    assert replayed.metrics["run"]["recording"]["compass"] == "/filter/quaternion and /imu/mag"
    want, got = files.read_tum(run.out_dir / "ekf.tum"), files.read_tum(replayed.out_dir / "ekf.tum")
    assert len(want) >= 14 and got.shape == want.shape
    np.testing.assert_array_equal(got[:, 0], want[:, 0])
    np.testing.assert_allclose(got[:, 1:], want[:, 1:], rtol=0, atol=1e-6)
    # fed the IMU alone, the replayed ekf differs: the compass was fed
    imu_only = scenarios.load("canal_multipath", set=overrides(lever="[0.0, 0.0, 0.0]"))
    without = replay(tmp_path / "bag", imu_only, tmp_path / "replay_imu", workers=1, report=False)
    assert "compass" not in without.metrics["run"]["recording"]
    assert np.abs(files.read_tum(without.out_dir / "ekf.tum")[:, 1:] - want[:, 1:]).max() > 1e-6


def copy_imu_bag(src: Path, dst: Path, frame_id: str, keep_tf_static: bool) -> None:
    """The bag's fixes, Imu (its frame_id changed) and, when asked, /tf_static again as `dst`."""
    store = typestore()
    with AnyReader([src], default_typestore=store) as reader, Writer(dst, version=8) as writer:
        wanted = {"/gps/fix", "/imu/data", *(["/tf_static"] if keep_tf_static else [])}
        out = {c.topic: writer.add_connection(c.topic, c.msgtype, typestore=store) for c in reader.connections if c.topic in wanted}
        for c, t, raw in reader.messages(connections=[c for c in reader.connections if c.topic in wanted]):
            if c.topic == "/imu/data":
                msg = reader.deserialize(raw, c.msgtype)
                msg.header.frame_id = frame_id
                raw = bytes(store.serialize_cdr(msg, c.msgtype))
            writer.write(out[c.topic], t, raw)


@pytest.mark.parametrize(
    ("frame_id", "tf_static", "message"),
    [
        ("xsens", True, "the Imu frame_id 'xsens' of /imu/data has no base_link -> xsens on /tf_static (it has: base_link -> gps, "),
        ("xsens", False, "the Imu frame_id 'xsens' of /imu/data is neither imu_link nor base_link, and the bag has no /tf_static"),
    ],
)
def test_an_imu_frame_off_the_mounts_is_one_line_exit_2(exported, tmp_path, frame_id, tf_static, message):
    copy_imu_bag(exported["bag"], tmp_path / "bag", frame_id, tf_static)
    scenario = tmp_path / "s.toml"
    scenario.write_text('name = "s"\nworld = "canal_lock"\n[[estimators]]\nid = "ekf"\nkind = "ekf"\nsensors = ["gnss", "imu"]\n')
    result = CliRunner().invoke(app, ["replay", str(tmp_path / "bag"), "--scenario", str(scenario), "--out", str(tmp_path / "out"), "--quiet"])
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert message in line
    assert not (tmp_path / "out").exists()


REAL_SCENARIO = """name = "husky"
world = "charles_river"
[[estimators]]
id = "ekf"
kind = "ekf"
sensors = ["gnss", "imu"]
params = { initial_pose = [-3030.47, 2434.65, 0.0] }  # the bag's first fix in charles_river's ENU (it is 4 km from its origin)
"""


def test_a_real_ros1_bags_imu_is_read_as_rosbags_reads_it():
    """robot_localization's test1.bag (no /tf_static, Imu in imu_link): every Imu message, batched between fixes, exactly."""
    place = Place((42.3539, -71.0878, 0.0), scenarios.load("charles_river").gnss.epoch_utc, imu_noise=(MTI630_GYRO, MTI630_ACCEL))
    recording = replay_bag.read(REAL_BAG, place)
    assert recording.imu_source == "/imu/data (frame imu_link; no /tf_static: its axes assumed base_link's)"
    batches = [e.samples for e in recording.events() if isinstance(e, ImuEvent)]
    with AnyReader([REAL_BAG]) as reader:
        connections = [c for c in reader.connections if c.topic == "/imu/data"]
        want = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections)]
    want.sort(key=lambda m: replay_bag.header_ns(m))
    assert sum(len(b) for b in batches) == len(want) == 11865
    np.testing.assert_array_equal(np.concatenate([b.gyro for b in batches]), [vec(m.angular_velocity) for m in want])
    np.testing.assert_array_equal(np.concatenate([b.accel for b in batches]), [vec(m.linear_acceleration) for m in want])
    stamps = np.concatenate([b.stamp for b in batches])
    np.testing.assert_array_equal(stamps, [recording.geo.seconds(replay_bag.header_ns(m)) for m in want])
    # its covariances (0.0004 (rad/s)^2, 0.009604 (m/s^2)^2) give the densities at its rate, not the scenario's fallback
    rate = 1.0 / np.median(np.diff(stamps))
    assert batches[0].gyro_noise == pytest.approx(math.sqrt(0.0004 / rate), rel=1e-3)
    assert batches[0].accel_noise == pytest.approx(math.sqrt(0.009604 / rate), rel=1e-3)


def test_a_gnss_and_imu_replay_of_the_real_bag_runs(tmp_path):
    scenario = tmp_path / "husky.toml"
    scenario.write_text(REAL_SCENARIO)
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["replay", str(REAL_BAG), "--scenario", str(scenario), "--out", str(out), "--no-report", "--quiet"])
    assert result.exit_code == 0, result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["run"]["recording"]["imu"] == "/imu/data (frame imu_link; no /tf_static: its axes assumed base_link's)"
    assert metrics["run"]["fixes"] == 989 and not metrics["run"]["failures"]
    assert metrics["estimators"]["ekf"]["available"] == 1.0
    tum = files.read_tum(out / "ekf.tum")
    assert len(tum) == 989 and np.isfinite(tum).all()
