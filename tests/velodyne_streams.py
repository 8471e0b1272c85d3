"""Synthetic Velodyne data-packet streams of any model, written as a libpcap capture: every laser returns on every firing
at a range of its own (`ranges`), so what a reader decodes can be checked against the model's own geometry and timing."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from scenarios.export.pcap import DATA_PORT, PCAP_HEADER, records
from scenarios.replay.velodyne import DATA, SensorModel

BANKS = (0xEEFF, 0xDDFF, 0xCCFF, 0xBBFF)
EPOCH_US = 1_718_460_000_000_000  # 2024-06-15 14:00:00 UTC


def ranges(model: SensorModel) -> np.ndarray:
    """Each laser's range (m): 10 m plus 0.25 m per laser id."""
    return 10.0 + 0.25 * np.arange(model.lasers)


def stream(
    model: SensorModel,
    path: Path,
    *,
    rate_hz: float = 10.0,
    packets: int = 400,
    resolution_m: float = 0.002,
    product_id: int | None = None,
    packet_s: float | None = None,
    start_deg: float = 90.0,
) -> np.ndarray:
    """Write `packets` data packets of `model` spinning at `rate_hz` to `path`; returns them. Blocks follow the model's layout:
    one azimuth per firing sequence, which spans 1 block (32 lasers), 1 block holding two sequences (16 lasers) or 4 blocks
    (128 lasers, one bank of 32 each)."""
    span = packet_s if packet_s is not None else model.packet_s[0]
    banks = max(model.lasers // 32, 1)
    step = model.azimuth_s[0]  # time between two block azimuths
    data = np.zeros(packets, DATA)
    blocks = data["block"]
    sequence = np.arange(packets * 12).reshape(packets, 12) // banks
    blocks["flag"] = np.array(BANKS[:banks] * (12 // banks), dtype=np.uint16)[None, :]
    blocks["azimuth"] = np.rint((start_deg + 360.0 * rate_hz * step * sequence) * 100).astype(np.int64) % 36000
    channel = np.arange(32)
    laser = (np.arange(12)[:, None] % banks) * 32 + (channel[None, :] % model.lasers)  # a VLP-16 block: its 16 lasers twice
    blocks["laser"]["distance"] = np.rint(ranges(model)[laser] / resolution_m).astype(np.uint16)[None, :, :]
    blocks["laser"]["reflectivity"] = 40
    stamps_us = EPOCH_US + np.rint(np.arange(packets) * span * 1e6).astype(np.int64)
    data["stamp"] = stamps_us % 3_600_000_000
    data["return_mode"] = 0x37
    data["product"] = model.product_id if product_id is None else product_id
    path.write_bytes(PCAP_HEADER + records(data, stamps_us, DATA_PORT).tobytes())
    return data
