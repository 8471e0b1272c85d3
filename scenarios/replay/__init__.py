"""Replay of real recordings: a scenario's matchers and estimators over a rosbag2 (or ROS 1 bag) or a Velodyne pcap.

    replay("boat.mcap_dir", "my_boat.toml", "runs/boat") -> ReplayResult (run directory, metrics)

Modules: recording (time base, ENU origin, time order), clouds (PointCloud2 -> Scan), fixes (NMEA,
NavSatFix -> GnssFix), reports (a riverbench bag's unrounded receiver reports), bag and pcap (the
readers; a pcap's: capture (libpcap records), velodyne (which sensor), clocks (one timeline),
revolutions (whole ones only)), run (the replay and its run directory), anchor (where matcher odometry
starts), gates (which check refused most scans), metrics (what needs no truth), report.
"""

from __future__ import annotations

from scenarios.replay.run import ReplayResult, replay

__all__ = ["ReplayResult", "replay"]
