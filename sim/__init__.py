"""Simulation: vessel motion, the HDL-32E LiDAR, the GNSS receiver, seeded random streams."""
