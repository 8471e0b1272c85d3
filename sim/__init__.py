"""Simulation: vessel motion, the HDL-32E LiDAR, the GNSS receiver, seeded random streams."""

from riverbench.rng import stream
from sim.gnss import GnssReceiver
from sim.gnss_fix import GnssFix
from sim.lidar import HDL32E
from sim.scan import Scan
from sim.scene import Scene
from sim.traffic import Traffic, TrafficConfig, build_traffic
from sim.trajectory import Trajectory

__all__ = ["HDL32E", "GnssFix", "GnssReceiver", "Scan", "Scene", "Traffic", "TrafficConfig", "Trajectory", "build_traffic", "stream"]
