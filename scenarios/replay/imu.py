"""A bag's sensor_msgs/Imu read into riverbench.samples.ImuSamples in base_link, batched between scans and fixes as a run is.

The IMU's mount is the bag's /tf_static transform base_link -> the Imu messages' frame_id; a bag without
/tf_static is taken to have its IMU axes on base_link's (frame_id the scenario's `imu_link`, or base_link
itself), which the replay says in its recording's IMU source. Gyro and accelerometer are rotated into
base_link; the lever arm is not undone (its centripetal and tangential terms are below a boat's
accelerometer noise at the rates a boat turns, and the filters level with the batch's mean force).
The white-noise densities come back from the covariance's first diagonal element as the export writes
it (variance = density^2 x rate, Kalibr's discrete noise model, scenarios.export.ros_messages), else
(covariance unknown: 0 or -1) from the scenario's [imu] datasheet figures. Batches: the samples since the
previous scan or fix form one ImuEvent just before it, as scenarios.pipeline.inertial weaves a run's.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from riverbench.samples import ImuSamples
from scenarios.pipeline.inertial import ImuEvent

BASE_FRAME = "base_link"
SCENARIO_FRAME = "imu_link"
"""The frame riverbench's export and xsens_mti_driver give the IMU (scenarios.export.ros_messages.IMU_FRAME)."""


@dataclass(frozen=True)
class ImuReading:
    """One Imu message in base_link: stamp (replay seconds), gyro rad/s, accel m/s^2 (specific force), its noise densities."""

    stamp: float
    gyro: np.ndarray
    accel: np.ndarray
    gyro_noise: float
    accel_noise: float


@dataclass(frozen=True)
class ImuMount:
    """base_link <- IMU rotation, what it came from (for the user), and the densities to use when a message gives none."""

    rotation: np.ndarray
    source: str
    gyro_noise: float
    accel_noise: float
    rate_hz: float


def transforms(tf_messages: Iterable) -> dict[str, tuple[str, np.ndarray]]:
    """child frame -> (parent frame, 3x3 rotation parent <- child) of tf2_msgs/TFMessage messages."""
    out = {}
    for message in tf_messages:
        for t in message.transforms:
            q = t.transform.rotation
            out[t.child_frame_id] = (t.header.frame_id, Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix())
    return out


def mount(path, topic: str, frame_id: str, static: dict[str, tuple[str, np.ndarray]] | None, noise: tuple[float, float], rate_hz: float) -> ImuMount:
    """The IMU's rotation onto base_link by the module's rules; a one-line ValueError when its frame does not fit them."""
    if frame_id == BASE_FRAME:
        return ImuMount(np.eye(3), f"{topic} (frame {BASE_FRAME})", *noise, rate_hz)
    if static is not None:
        parent, rotation = static.get(frame_id, ("", np.eye(3)))
        if parent != BASE_FRAME:
            known = ", ".join(f"{p} -> {c}" for c, (p, _) in sorted(static.items())) or "none"
            raise ValueError(f"{path}: the Imu frame_id {frame_id!r} of {topic} has no base_link -> {frame_id} on /tf_static (it has: {known})")
        return ImuMount(rotation, f"{topic} (frame {frame_id}, mount from /tf_static)", *noise, rate_hz)
    if frame_id != SCENARIO_FRAME:
        raise ValueError(
            f"{path}: the Imu frame_id {frame_id!r} of {topic} is neither {SCENARIO_FRAME} nor {BASE_FRAME}, and the bag has no /tf_static"
        )
    return ImuMount(np.eye(3), f"{topic} (frame {frame_id}; no /tf_static: its axes assumed base_link's)", *noise, rate_hz)


def density(covariance, rate_hz: float, fallback: float) -> float:
    """White-noise density of a message's diagonal variance at `rate_hz` (the fallback when the variance is not given)."""
    variance = float(covariance[0])
    return float(np.sqrt(variance / rate_hz)) if variance > 0 and rate_hz > 0 else fallback


def reading(msg, stamp: float, imu: ImuMount) -> ImuReading:
    """One sensor_msgs/Imu message in base_link."""
    gyro = np.array([msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z], dtype=float)
    accel = np.array([msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z], dtype=float)
    return ImuReading(
        stamp,
        imu.rotation @ gyro,
        imu.rotation @ accel,
        density(msg.angular_velocity_covariance, imu.rate_hz, imu.gyro_noise),
        density(msg.linear_acceleration_covariance, imu.rate_hz, imu.accel_noise),
    )


def batched(events: Iterator) -> Iterator:
    """The events with each run of ImuReadings joined into one ImuEvent, put out just before the next other event."""
    held: list[ImuReading] = []
    for event in events:
        if isinstance(event, ImuReading):
            held.append(event)
            continue
        if held:
            yield batch(held)
            held = []
        yield event
    if held:
        yield batch(held)


def batch(readings: list[ImuReading]) -> ImuEvent:
    """ImuReadings as one ImuEvent stamped at the last (noise densities: the last message's)."""
    samples = ImuSamples(
        np.array([r.stamp for r in readings]),
        np.array([r.gyro for r in readings]),
        np.array([r.accel for r in readings]),
        readings[-1].gyro_noise,
        readings[-1].accel_noise,
    )
    return ImuEvent(readings[-1].stamp, samples)
