"""Replay of recordings: a simulated run exported to a rosbag2 bag and to a Velodyne pcap, replayed through the same
scenario, gives the run's estimates again (the bag exactly, the pcap within its quantisation); topics are picked as
KISS-ICP picks them; the readers' field variants; bad input is one line and writes nothing."""

from __future__ import annotations

import dataclasses
import math
import shutil
import struct
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer
from scipy.spatial.transform import Rotation

import scenarios
import sim
import worlds
from scenarios.export import export
from scenarios.export.ros_messages import header, typestore
from scenarios.pipeline import files
from scenarios.replay import clouds, fixes, replay
from scenarios.replay.recording import Geo, Place, unix_ns
from scenarios.report.plots import read_csv
from sim.geodesy import LocalFrame
from sim.gnss_fix import GnssFix, SatelliteReport
from sim.lidar import HDL32E_ELEVATION_DEG
from sim.nmea.epochs import Splitter

STRETCH = "stretch={start_m = 350.0, end_m = 356.0}"  # canal_multipath: 3.1 s, 31 scans, 16 fixes (NLOS, 14 m off)
SMOOTHED = ("hdop_switch", "ekf", "pf")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """The simulated run, its rosbag2 and pcap exports, and their replays. The estimators that align their start on
    GPS travel are given the true start pose, so that all of them have estimates over these 3 s."""
    root = tmp_path_factory.mktemp("replay")
    scenario = scenarios.load("canal_multipath", set=[STRETCH])
    trajectory = sim.Trajectory(
        worlds.load(scenario.world, **scenario.world_params), seed=scenario.seed, **scenario.vessel.model_dump(exclude={"seed"})
    )
    pose = trajectory.pose(scenario.stretch.times(trajectory)[0])
    start = f"[{pose[0, 3]:.4f}, {pose[1, 3]:.4f}, {math.degrees(math.atan2(pose[1, 0], pose[0, 0])):.4f}]"
    scenario = scenarios.load("canal_multipath", set=[STRETCH, *(f"estimators.{e}.params.initial_pose={start}" for e in SMOOTHED)])
    run = scenarios.run(scenario, root / "run", workers=1, report=False)
    export(run.out_dir, "rosbag2", root / "bag")
    export(run.out_dir, "pcap", root / "run.pcap")
    return {
        "root": root,
        "scenario": scenario,
        "run": run.out_dir,
        "bag": replay(root / "bag", scenario, root / "replay-bag", workers=1, report=True),
        "pcap": replay(root / "run.pcap", scenario, root / "replay-pcap", workers=1, report=False),
    }


def tum(path) -> np.ndarray:
    """A TUM file's rows."""
    return files.read_tum(path)


def poses(rows: np.ndarray) -> np.ndarray:
    """(N, 4, 4) poses of TUM rows."""
    out = np.tile(np.eye(4), (len(rows), 1, 1))
    out[:, :3, :3] = Rotation.from_quat(rows[:, 4:]).as_matrix()
    out[:, :3, 3] = rows[:, 1:4]
    return out


def odometry(rows: np.ndarray) -> np.ndarray:
    """The poses relative to the first (a matcher's odometry, whatever it was chained from)."""
    p = poses(rows)
    return np.linalg.inv(p[0]) @ p


def ids(scenario) -> tuple[list[str], list[str]]:
    """Estimator ids and matcher ids."""
    return [e.id for e in scenario.estimators], [m.id for m in scenario.matchers]


def test_bag_replay_gives_the_simulated_estimates(recorded):
    run, out = recorded["run"], recorded["bag"].out_dir
    estimators, matchers = ids(recorded["scenario"])
    for eid in estimators:
        want, got = tum(run / f"{eid}.tum"), tum(out / f"{eid}.tum")
        assert len(want) >= 30 and got.shape == want.shape
        np.testing.assert_array_equal(got[:, 0], want[:, 0])
        # identical to the files' print precision (1 um, 1e-9): NMEA's rounding is undone by the NavSatFix of each epoch
        np.testing.assert_allclose(got[:, 1:], want[:, 1:], rtol=0, atol=1.5e-6)
    for mid in matchers:
        want, got = tum(run / f"{mid}.tum"), tum(out / f"{mid}.tum")
        np.testing.assert_array_equal(got[:, 0], want[:, 0])
        # chained from the truth in simulation, from the first estimate here: the same odometry (rounded at other digits)
        np.testing.assert_allclose(odometry(got), odometry(want), rtol=0, atol=2e-6)
    sim_fixes, replay_fixes = read_csv(run / "gps.csv"), read_csv(out / "gps.csv")
    for column in (
        "t",
        "quality",
        "e",
        "n",
        "u",
        "lat",
        "lon",
        "alt",
        "num_sats",
        "hdop",
        *(f"{e}.trusted" for e in estimators),
        *(f"{e}.statistic" for e in estimators),  # the ekf's C/N0 monitor too: the bag's /gps/report gives it C/N0 unrounded
    ):
        np.testing.assert_array_equal(replay_fixes[column], sim_fixes[column], err_msg=column)
    assert (out / "gps.nmea").read_bytes() == (run / "gps.nmea").read_bytes()  # the recorded sentences, verbatim


def test_the_bag_exported_from_the_run_carries_its_estimates(recorded):
    """`riverbench export RUN_DIR`: each estimator's nav_msgs/Odometry topic is the run's <id>.tum, pose for pose."""
    run, scenario = recorded["run"], recorded["scenario"]
    with AnyReader([recorded["root"] / "bag"]) as reader:
        for eid in ids(scenario)[0]:
            connections = [c for c in reader.connections if c.topic == f"/riverbench/{eid}/odom"]
            odometry_msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections)]
            want = tum(run / f"{eid}.tum")
            got = np.array(
                [[*(getattr(m.pose.pose.position, a) for a in "xyz"), *(getattr(m.pose.pose.orientation, a) for a in "xyzw")] for m in odometry_msgs]
            )
            assert len(want) >= 30 and got.shape == want[:, 1:].shape
            stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in odometry_msgs])
            np.testing.assert_allclose(stamps, want[:, 0], rtol=0, atol=1e-6)  # both UNIX time (TUM: 9 decimals)
            # the TUM file's print precision (1 um, 1e-9); its z is the waterline (0), the Odometry's the estimate's height
            np.testing.assert_allclose(got[:, [0, 1, 3, 4, 5, 6]], want[:, [1, 2, 4, 5, 6, 7]], rtol=0, atol=1.5e-6)
            assert np.all(want[:, 3] == 0)


def test_pcap_replay_within_its_quantisation(recorded):
    run, out = recorded["run"], recorded["pcap"].out_dir
    for mid in ids(recorded["scenario"])[1]:
        want, got = tum(run / f"{mid}.tum"), tum(out / f"{mid}.tum")
        # scans cut at the revolution start, stamped to the microsecond (the run's files carry nanoseconds)
        np.testing.assert_array_equal(*(np.round(files.read_tum(d / f"{mid}.tum", scenario_time=True)[:, 0] * 1e6) for d in (run, out)))
        a, b = odometry(want), odometry(got)
        # measured 5.7 cm over the 6 m (3.0 mm before gicp's co-moving screen: on a few points at the canal's edges the
        # 2 mm range and 0.01 deg azimuth quantisation flips its static/moving-with-the-sensor decision)
        assert np.abs(a[:, :2, 3] - b[:, :2, 3]).max() < 0.1
        # the canal's weakly observed vertical: where gicp finds a translation degenerate it keeps its motion prior, and the
        # 2 mm quantisation flips that decision on a few scans (measured 6.3 cm over the 3 s)
        assert np.abs(a[:, 2, 3] - b[:, 2, 3]).max() < 0.1
        angle = Rotation.from_matrix(np.linalg.inv(a[:, :3, :3]) @ b[:, :3, :3]).magnitude()
        # measured 0.06 deg on an Intel Xeon (0.02 before gicp weighed its normals by planarity, which quantisation moves);
        # 0.134 deg on an AMD EPYC with the same code and packages (5971f78): the CPUs' last bits flip other decisions
        assert np.degrees(angle).max() < 0.2
    want, got = tum(run / "ekf.tum"), tum(out / "ekf.tum")
    assert np.hypot(*(want[:, 1:3] - got[:, 1:3]).T).max() < 0.1  # odometry only in these 3 s (its monitor trusts no fix yet): 5.7 cm
    # GPRMC's time of 0.01 s puts each fix 1.1 ms before the scan it shares its stamp with in simulation, so gps_only
    # takes it a scan earlier: its pose at scan k is the simulated one at scan k + 1, to RMC's 5 decimals of minutes
    want, got = tum(run / "gps_only.tum"), tum(out / "gps_only.tum")
    assert len(got) == len(want) + 1
    assert np.hypot(*(want[:, 1:3] - got[:-1, 1:3]).T).max() < 0.015
    sim_fixes, replay_fixes = read_csv(run / "gps.csv"), read_csv(out / "gps.csv")
    assert np.abs(replay_fixes["t"] - sim_fixes["t"]).max() <= 0.0051
    assert np.hypot(replay_fixes["e"] - sim_fixes["e"], replay_fixes["n"] - sim_fixes["n"]).max() < 0.015
    measured = np.isin(replay_fixes["quality"], sorted(fixes.SATELLITE_SOLUTIONS))
    assert (replay_fixes["hdop"][measured] == fixes.NOMINAL_HDOP).all() and (replay_fixes["quality"] == sim_fixes["quality"]).all()
    assert np.isnan(replay_fixes["hdop"][replay_fixes["quality"] == 6]).all()


def test_matcher_odometry_starts_from_an_estimate_with_a_heading(recorded):
    """gps_only has the first pose but no heading (yaw 0): the odometry is laid on the first estimate that knows its
    heading, and lands on the true track (the run's groundtruth.tum) instead of turning about its start."""
    result = recorded["bag"]
    anchor = result.metrics["run"]["anchor"]
    assert anchor["heading"] == "estimate" and anchor["estimator"] in SMOOTHED
    truth, gicp = poses(tum(recorded["run"] / "groundtruth.tum")), poses(tum(result.out_dir / "gicp.tum"))
    yaw = lambda p: np.degrees(np.arctan2(p[:, 1, 0], p[:, 0, 0]))
    off = np.hypot(*(truth[:, :2, 3] - gicp[:, :2, 3]).T)
    assert off.max() < 0.1 and np.abs(yaw(truth) - yaw(gicp)).max() < 0.5  # measured 0.011 m, 0.008 deg


def test_run_directory_holds_no_truth(recorded):
    result = recorded["bag"]
    estimators, matchers = ids(recorded["scenario"])
    names = {p.name for p in result.out_dir.iterdir()}
    assert names == {
        "scenario.toml",
        "metrics.json",
        "gps.csv",
        "gps.nmea",
        "report.md",
        "report.html",
        "plots",
        *(f"{k}.tum" for k in estimators + matchers),
    }
    assert not (recorded["pcap"].out_dir / "report.md").exists()
    assert not [p for p in recorded["root"].iterdir() if p.name.startswith(".")]
    m = result.metrics
    assert m["run"]["scans"] == 31 and m["run"]["fixes"] == 16 and m["run"]["failures"] == []
    assert m["run"]["recording"]["origin_from"] == "world" and m["run"]["recording"]["time_zero_utc"].startswith("2018-07-29T15:00:00")
    assert set(m["matchers"]["gicp"]) == {"success", "gated", "degenerate", "hz", "ms", "points", "failed"}
    node = m["estimators"]["gps_only"]["against_gps"]
    fixes = read_csv(result.out_dir / "gps.csv")
    step = np.hypot(np.diff(fixes["e"]), np.diff(fixes["n"])).max()  # the GPS track's largest move from one fix to the next
    assert node["fixes"] == 15 and node["trusted"] == 1.0 and node["max"] <= step + 1e-3  # one scan behind its fixes at most
    assert "err_h" not in read_csv(result.out_dir / "gps.csv")
    assert "Estimators against GPS" in (result.out_dir / "report.md").read_text()


def copy_bag(src, dst, seconds: float, duplicate: dict[str, str] | None = None, edit=None) -> None:
    """The bag's first `seconds` again as `dst`, with topics `duplicate`d and messages changed by edit(topic, index, msg)."""
    store, duplicate = typestore(), duplicate or {}
    with AnyReader([src], default_typestore=store) as reader:
        writer = Writer(dst, version=8)
        with writer:
            out = {c.topic: writer.add_connection(c.topic, c.msgtype, typestore=store) for c in reader.connections}
            out |= {new: writer.add_connection(new, reader.topics[of].msgtype, typestore=store) for new, of in duplicate.items()}
            counts: dict[str, int] = {}
            for c, t, raw in reader.messages():
                if t > reader.start_time + seconds * 1e9:
                    break
                if edit is not None:
                    msg = edit(c.topic, counts.setdefault(c.topic, 0), reader.deserialize(raw, c.msgtype))
                    raw = bytes(store.serialize_cdr(msg, c.msgtype))
                counts[c.topic] = counts.get(c.topic, 0) + 1
                for topic in [c.topic, *(new for new, of in duplicate.items() if of == c.topic)]:
                    writer.write(out[topic], t, raw)


def test_topics_picked_as_kiss_icp_picks_them(recorded, tmp_path):
    bag = tmp_path / "two_clouds"
    copy_bag(recorded["root"] / "bag", bag, 0.55, duplicate={"/points_raw": "/velodyne_points"})
    scenario = recorded["scenario"]
    with pytest.raises(ValueError, match=r"2 PointCloud2 topics \(/points_raw, /velodyne_points\): pick one with --lidar-topic") as error:
        replay(bag, scenario, tmp_path / "out")
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match=r"no PointCloud2 topic '/lidar'; the bag's: /points_raw \(PointCloud2\), /velodyne_points"):
        replay(bag, scenario, tmp_path / "out", lidar_topic="/lidar")
    with pytest.raises(ValueError, match=r"no Sentence or NavSatFix topic '/velodyne_points'"):
        replay(bag, scenario, tmp_path / "out", lidar_topic="/points_raw", gps_topic="/velodyne_points")
    picked = replay(bag, scenario, tmp_path / "out", lidar_topic="/points_raw", workers=2, report=False)  # gicp in a worker process
    assert picked.recording.lidar_source == "/points_raw" and picked.metrics["run"]["scans"] == 6 and picked.metrics["run"]["workers"] == 2
    want = odometry(tum(recorded["run"] / "gicp.tum")[:6])
    np.testing.assert_allclose(odometry(tum(picked.out_dir / "gicp.tum")), want, rtol=0, atol=2e-6)
    # NavSatFix alone: positions and HDOP exact, no satellites: gps_only as simulated in x, y and orientation. Not in z:
    # nmea_navsat_driver's NavSatFix carries no VDOP (its up variance is (4 HDOP EPE)^2), so the height filter weighs
    # its default 2 HDOP instead of the receiver's VDOP (measured 4e-5 m off)
    navsat = replay(bag, scenario, tmp_path / "navsat", lidar_topic="/velodyne_points", gps_topic="/gps/fix", report=False)
    want, got = tum(recorded["run"] / "gps_only.tum"), tum(navsat.out_dir / "gps_only.tum")
    horizontal_and_orientation = [1, 2, 4, 5, 6, 7]
    np.testing.assert_allclose(got[:, horizontal_and_orientation], want[: len(got), horizontal_and_orientation], rtol=0, atol=1.5e-6)
    assert not (navsat.out_dir / "gps.nmea").exists()


def test_bad_input_is_one_line_and_writes_nothing(recorded, tmp_path):
    scenario = recorded["scenario"]
    (tmp_path / "notes.txt").write_text("not a bag\n")
    (tmp_path / "empty").mkdir()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").touch()
    (tmp_path / "header.pcap").write_bytes(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1))
    shutil.copy(recorded["root"] / "run.pcap", tmp_path / "copy.pcap")
    store = typestore()
    with Writer(tmp_path / "no_points", version=8) as writer:  # a bag without any topic a replay can use
        log = writer.add_connection("/rosout_text", "std_msgs/msg/String", typestore=store)
        writer.write(log, 1, bytes(store.serialize_cdr(store.types["std_msgs/msg/String"](data="hello"), "std_msgs/msg/String")))
    cases = [
        ("missing", None, "no such bag"),
        ("no_points", None, r"no_points: no Sentence or NavSatFix topic$"),  # without a cloud it would replay GNSS-only
        ("notes.txt", None, "not a readable bag"),
        ("empty", None, "not a readable bag"),
        ("header.pcap", None, "no Velodyne data packets"),
        ("copy.pcap", "/velodyne_points", "a pcap has no topics"),
    ]
    before = set(tmp_path.iterdir())
    for name, topic, message in cases:
        with pytest.raises(ValueError, match=message) as error:
            replay(tmp_path / name, scenario, tmp_path / "out", lidar_topic=topic)
        assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="not empty"):
        replay(tmp_path / "copy.pcap", scenario, tmp_path / "full")
    assert set(tmp_path.iterdir()) == before


def test_a_bad_scan_is_a_recorded_failure(recorded, tmp_path):
    def break_third_cloud(topic, index, msg):
        """Rename the third cloud's x field."""
        if topic != "/velodyne_points" or index != 2:
            return msg
        return dataclasses.replace(msg, fields=[dataclasses.replace(f, name="q" if f.name == "x" else f.name) for f in msg.fields])

    copy_bag(recorded["root"] / "bag", tmp_path / "bad", 0.55, edit=break_third_cloud)
    result = replay(tmp_path / "bad", recorded["scenario"], tmp_path / "out", report=False)
    assert result.metrics["run"]["scans"] == 5
    [failure] = result.metrics["run"]["failures"]
    assert failure["component"] == "scan" and failure["id"] == "/velodyne_points" and "no field x" in failure["reason"]
    assert failure["stamp"] == pytest.approx(files.read_tum(recorded["run"] / "gicp.tum", scenario_time=True)[2, 0], abs=1e-6)


def cloud(points: np.ndarray, ns: int = 5_000_000_000):
    """A PointCloud2 of a structured array (each field a PointField at its offset)."""
    store = typestore()
    field = store.types["sensor_msgs/msg/PointField"]
    kinds = {"f4": 7, "f8": 8, "u2": 4, "u4": 6, "u1": 2}
    fields = [field(name=n, offset=o, datatype=kinds[dt.str[1:]], count=1) for n, (dt, o) in points.dtype.fields.items()]
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=header(store, ns, "lidar"),
        height=1,
        width=len(points),
        fields=fields,
        is_bigendian=False,
        point_step=points.dtype.itemsize,
        row_step=points.dtype.itemsize * len(points),
        data=points.view(np.uint8),
        is_dense=True,
    )


def test_cloud_field_variants():
    elevation = np.radians(HDL32E_ELEVATION_DEG)
    xyz = 10.0 * np.stack([np.cos(elevation) * np.cos(0.3), np.cos(elevation) * np.sin(0.3), np.sin(elevation)], axis=1)
    bare = np.zeros(32, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "u1"), ("t", "<u4")])
    bare["x"], bare["y"], bare["z"], bare["i"], bare["t"] = *xyz.T, 7, np.arange(32) * 1000
    scan = clouds.scan(cloud(bare), 2.0, 5.0)
    np.testing.assert_array_equal(scan.points["ring"], np.arange(32))  # laser ids from elevation, without a ring field
    np.testing.assert_allclose(scan.points["time"], np.arange(32) * 1e-6)  # ouster's integer nanoseconds
    assert scan.stamp == 2.0 and (scan.points["intensity"] == 7).all()
    hesai = np.zeros(2, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("timestamp", "<f8")])
    hesai["x"], hesai["z"], hesai["timestamp"] = 5.0, (0.0, 4.0), (1.7e9 + 0.25, 1.7e9 + 0.5)  # absolute; 38.7 deg: no HDL-32E beam
    scan = clouds.scan(cloud(hesai), 2.0, 1.7e9)
    np.testing.assert_allclose(scan.points["time"], [0.25, 0.5])
    assert (scan.points["ring"] == 0).all() and (scan.points["intensity"] == 0).all()
    no_x = np.zeros(2, [("y", "<f4"), ("z", "<f4")])
    with pytest.raises(ValueError, match="no field x"):
        clouds.scan(cloud(no_x), 0.0, 0.0)
    short = dataclasses.replace(cloud(bare), data=bare.view(np.uint8)[:100])
    with pytest.raises(ValueError, match="too few"):
        clouds.scan(short, 0.0, 0.0)


def test_nmea_and_rmc_read_back():
    origin = (42.3539, -71.1106, 5.0)
    epoch = datetime(2024, 6, 15, 14, tzinfo=UTC)
    geo = Geo.choose(Place(origin, epoch), unix_ns(epoch) + 5_000_000_000, None)
    enu = np.array([120.0, -35.0, 12.0])
    lat, lon, alt = LocalFrame.at(*origin).geodetic_of_enu(enu)
    sats = (SatelliteReport(3, 120.4, 35.6, 44.3, True), SatelliteReport(7, 250.0, 12.2, 0.0, False))
    fix = GnssFix(
        stamp=12.5,
        lat=lat,
        lon=lon,
        alt=alt,
        enu=enu,
        quality=1,
        num_sats=1,
        hdop=0.876,
        vdop=1.234,
        pdop=1.5,
        sats=sats,
        utc="2024-06-15T14:00:12.500000+00:00",
        speed_mps=2.0,
        course_deg=90.0,
    )
    got = fixes.from_nmea(12.5, fix.nmea(), geo)
    assert got.quality == 1 and got.num_sats == 1 and got.hdop == 0.88 and got.vdop == 1.23 and got.truth is None
    assert np.abs(got.enu - enu).max() < 0.015 and got.course_deg == 90.0 and abs(got.speed_mps - 2.0) < 1e-3
    assert got.sats == (SatelliteReport(3, 120.0, 36.0, 44.0, True), SatelliteReport(7, 250.0, 12.0, 0.0, False))
    for quality in (1, 6, 0):
        rmc = fixes.from_nmea(12.5, [sim.nmea.rmc(dataclasses.replace(fix, quality=quality))], geo)
        # a satellite solution without DOPs is weighed as an open-sky one; a coast or no fix has no geometry (NaN)
        assert rmc.quality == quality and (rmc.hdop == fixes.NOMINAL_HDOP if quality == 1 else np.isnan(rmc.hdop))
        assert abs(rmc.enu[2]) < 0.01 if quality else np.isnan(rmc.enu).all()  # no altitude: the origin's height
    epochs = Splitter()
    lines = fix.nmea() + fixes_later(fix).nmea()
    closed = [[(x.tag, x.text) for x in c] for c in (epochs.add(k, line) for k, line in enumerate(lines)) if c]
    assert closed == [list(enumerate(fix.nmea()))] and [(x.tag, x.text) for x in epochs.close()] == list(enumerate(lines))[4:]


def fixes_later(fix: GnssFix) -> GnssFix:
    """The same fix 0.2 s later."""
    return dataclasses.replace(fix, stamp=fix.stamp + 0.2, utc="2024-06-15T14:00:12.700000+00:00")


def test_time_base_and_origin_rules():
    epoch = datetime(2024, 6, 15, 14, tzinfo=UTC)
    place = Place((42.3539, -71.1106, 5.0), epoch)
    near = Geo.choose(place, unix_ns(epoch) + 3_000_000_000, (42.36, -71.10, 3.0))
    assert near.zero_ns == unix_ns(epoch) and near.origin_source == "world" and near.seconds(unix_ns(epoch) + 1_500_000_000) == 1.5
    later = datetime(2025, 3, 1, 9, tzinfo=UTC)
    far = Geo.choose(place, unix_ns(later), (48.85, 2.35, 35.0))
    assert far.zero_ns == unix_ns(later) and far.origin == (48.85, 2.35, 35.0) and far.origin_source == "first fix"
    assert np.abs(far.enu(48.85, 2.35, 35.0)).max() < 1e-6


def test_the_replay_command_writes_a_run_directory_and_refuses_bad_input_in_one_line(tmp_path):
    import subprocess
    import sys

    from scenarios.export import export

    export("canal_multipath", "mcap", tmp_path / "bag", set=["stretch={start_s = 60.0, end_s = 61.0}"])
    cli = [sys.executable, "-m", "scenarios.cli", "replay"]
    ok = subprocess.run(
        [*cli, "bag", "--scenario", "canal_multipath", "--out", "run", "--quiet", "--no-report"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert ok.returncode == 0, ok.stderr
    assert "replayed 10 scans" in ok.stdout and (tmp_path / "run" / "gicp.tum").exists()
    for args, message in (
        (["nothing", "--scenario", "canal_multipath"], "no such bag, pcap or NMEA log"),
        (["bag", "--scenario", "canal_multipath", "--lidar-topic", "/x"], "/x"),
    ):
        bad = subprocess.run([*cli, *args], cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert bad.returncode == 2 and message in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_a_capture_takes_its_gps_from_an_nmea_log(recorded, tmp_path):
    """`--nmea`: the run's own NMEA log (GGA, RMC, GSA, GSV) replaces the capture's GPRMC; a log of another day is refused."""
    run = recorded["run"]
    result = replay(recorded["root"] / "run.pcap", recorded["scenario"], tmp_path / "out", nmea=run / "gps.nmea", report=False)
    assert result.recording.gps_source.startswith("NMEA log gps.nmea") and result.metrics["run"]["recording"]["nmea"]["epochs"] == 16
    sim_fixes, got = read_csv(run / "gps.csv"), read_csv(result.out_dir / "gps.csv")
    assert np.abs(got["t"] - sim_fixes["t"]).max() <= 0.0051  # NMEA's 0.01 s
    np.testing.assert_array_equal(got["quality"], sim_fixes["quality"])
    np.testing.assert_array_equal(got["num_sats"], sim_fixes["num_sats"])
    np.testing.assert_allclose(got["hdop"], sim_fixes["hdop"], atol=0.005)  # GGA's 2 decimals, not the capture's nominal HDOP
    assert np.hypot(got["e"] - sim_fixes["e"], got["n"] - sim_fixes["n"]).max() < 0.015
    rtk = Path(__file__).parent / "data" / "nmea" / "nmea_navsat_driver_rtk_nmea.log"
    with pytest.raises(ValueError, match="do not overlap") as error:
        replay(recorded["root"] / "run.pcap", recorded["scenario"], tmp_path / "other", nmea=rtk)
    assert "\n" not in str(error.value) and not (tmp_path / "other").exists()
    with pytest.raises(ValueError, match="has none"):
        replay(rtk, recorded["scenario"], tmp_path / "alone", nmea=rtk)
