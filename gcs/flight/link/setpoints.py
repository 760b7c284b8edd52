"""Setpoints: a plan (or a transfer flight) sampled at the stream rate, in a vehicle's frame.

A `SetpointTrack` holds one vehicle's SET_POSITION_TARGET_LOCAL_NED values for ticks 0, 1, 2,
... of a fixed-rate stream (position, velocity and acceleration feed-forward in that vehicle's
LOCAL_NED, and a fixed yaw). Tracks are computed once, before streaming, so the streaming loop
only indexes arrays. Past its last tick a track holds its final state at rest.

- `plan_tracks` samples a `planner.Plan` with its exact motion between steps
  (`Plan.sample`, i.e. `planner.model.dynamics.interpolate`) and converts it with `gcs.frames`.
- `transfer_track` is the climb from home to the plan's start: vertical first, then
  horizontal, each a smooth rest-to-rest (quintic, minimum-jerk) profile.
- `hold_track` holds one position.

The message fields follow MAVLink common.xml and PX4's mavlink_receiver; their encoding
(frame, type mask, `time_boot_ms`) is defined once in `gcs.wire`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gcs import frames
from gcs.wire import MAV_FRAME_LOCAL_NED, MAX_RATE_HZ, TYPE_MASK_POS_VEL_ACC_YAW
from planner.types import FloatArray

__all__ = [
    "DEFAULT_RATE_HZ",
    "Setpoint",
    "SetpointTrack",
    "hold_track",
    "plan_tracks",
    "spliced",
    "transfer_track",
]


DEFAULT_RATE_HZ = 20.0
#: One 3-vector of a setpoint (x, y, z).
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Setpoint:
    """One SET_POSITION_TARGET_LOCAL_NED's values (LOCAL_NED of the target vehicle)."""

    position: tuple[float, float, float]
    """x, y, z (m), z down."""
    velocity: tuple[float, float, float]
    """vx, vy, vz (m/s)."""
    acceleration: tuple[float, float, float]
    """afx, afy, afz (m/s^2), feed-forward."""
    yaw: float
    """NED heading (rad)."""

    def fields(self, target_system: int, target_component: int, boot_ms: int) -> dict[str, Any]:
        """Keyword arguments of pymavlink's `set_position_target_local_ned_encode`."""
        x, y, z = self.position
        vx, vy, vz = self.velocity
        afx, afy, afz = self.acceleration
        return {
            "time_boot_ms": boot_ms,
            "target_system": target_system,
            "target_component": target_component,
            "coordinate_frame": MAV_FRAME_LOCAL_NED,
            "type_mask": TYPE_MASK_POS_VEL_ACC_YAW,
            "x": x, "y": y, "z": z,
            "vx": vx, "vy": vy, "vz": vz,
            "afx": afx, "afy": afy, "afz": afz,
            "yaw": self.yaw,
            "yaw_rate": 0.0,
        }


class SetpointTrack:
    """One vehicle's setpoints at ticks 0..M-1 of a `rate` Hz stream (LOCAL_NED)."""

    __slots__ = ("_ticks", "acceleration", "position", "rate", "velocity", "yaw")

    def __init__(self, position: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike,
                 yaw: float, rate: float) -> None:
        self.position: FloatArray = np.asarray(position, dtype=float)
        self.velocity: FloatArray = np.asarray(velocity, dtype=float)
        self.acceleration: FloatArray = np.asarray(acceleration, dtype=float)
        self.yaw = float(yaw)
        self.rate = float(rate)
        if not (self.position.shape == self.velocity.shape == self.acceleration.shape):
            raise ValueError("position, velocity and acceleration must have the same shape")
        if self.position.ndim != 2 or self.position.shape[1] != 3 or len(self.position) == 0:
            raise ValueError("a track needs arrays of shape (M, 3) with M >= 1")
        # Each tick's values as Python floats, made once: a setpoint built from them costs
        # no numpy indexing per tick, and the flight record it lands in pickles and
        # serialises as plain floats (numpy scalars pickle ten times slower, which the
        # vehicle process paid holding its interpreter lock).
        rows = zip(self.position.tolist(), self.velocity.tolist(), self.acceleration.tolist(),
                   strict=True)
        self._ticks: list[tuple[Vec3, Vec3, Vec3]] = [
            ((p[0], p[1], p[2]), (v[0], v[1], v[2]), (a[0], a[1], a[2])) for p, v, a in rows]

    def __len__(self) -> int:
        return len(self.position)

    @property
    def duration(self) -> float:
        """Time of the last tick (s)."""
        return (len(self) - 1) / self.rate

    @property
    def final_position(self) -> FloatArray:
        final: FloatArray = self.position[-1]
        return final

    def at(self, tick: int) -> Setpoint:
        """The setpoint for `tick`; before 0 the first position at rest, past the end the final
        position at rest (as `planner.model.dynamics.interpolate` does outside the horizon)."""
        if tick >= len(self) or tick < 0:
            p = self._ticks[-1 if tick >= 0 else 0][0]
            return Setpoint(p, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), self.yaw)
        p, v, a = self._ticks[tick]
        return Setpoint(p, v, a, self.yaw)


def plan_tracks(plan: Any, homes_world: Sequence[ArrayLike] | ArrayLike, rate: float,
                yaw_world: float = 0.0, extra_s: float = 0.0) -> list[SetpointTrack]:
    """Every vehicle's track for `plan` (a `planner.Plan`), in plan vehicle order.

    Tick k is flight time k / rate, sampled with the plan's exact motion; the track covers the
    horizon plus `extra_s` seconds (holding the goal at rest). `homes_world[i]` is vehicle i's
    LOCAL_NED origin in the world frame.
    """
    _check_rate(rate)
    homes = np.asarray(homes_world, dtype=float).reshape(len(plan.vehicles), 3)
    count = int(np.floor((plan.scenario.horizon + extra_s) * rate + 1e-9)) + 1
    times = np.arange(count) / rate
    sample = plan.sample(times)
    yaw = frames.world_yaw_to_ned(yaw_world)
    return [
        SetpointTrack(
            frames.world_to_ned(sample.position[i], homes[i]),
            frames.world_vector_to_ned(sample.velocity[i]),
            frames.world_vector_to_ned(sample.acceleration[i]),
            yaw,
            rate,
        )
        for i in range(len(plan.vehicles))
    ]


def hold_track(position_ned: ArrayLike, yaw_ned: float, rate: float) -> SetpointTrack:
    """A single setpoint holding `position_ned` at rest."""
    p = np.asarray(position_ned, dtype=float).reshape(1, 3)
    return SetpointTrack(p, np.zeros((1, 3)), np.zeros((1, 3)), yaw_ned, rate)


def spliced(head: SetpointTrack, tick: int, tail: SetpointTrack) -> SetpointTrack:
    """`head`'s ticks before `tick`, then `tail` from its tick 0 on: a replan's track, whose
    setpoints before the switch tick are the flying plan's (`gcs.flight.replan.replan`)."""
    keep = max(0, min(tick, len(head)))
    pad = max(0, tick - len(head))  # switching after head's end: its final state at rest
    parts = [head.position[:keep], np.repeat(head.final_position[None, :], pad, axis=0),
             tail.position]
    zeros = np.zeros((pad, 3))
    return SetpointTrack(np.concatenate(parts),
                         np.concatenate([head.velocity[:keep], zeros, tail.velocity]),
                         np.concatenate([head.acceleration[:keep], zeros, tail.acceleration]),
                         tail.yaw, tail.rate)


def _quintic(distance: float, duration: float, t: FloatArray) -> tuple[FloatArray, ...]:
    """Rest-to-rest minimum-jerk profile: (s, ds, dds) along a segment of `distance`."""
    if duration <= 0.0:
        z = np.zeros_like(t)
        return np.full_like(t, distance), z, z
    u = np.clip(t / duration, 0.0, 1.0)
    s = distance * (10 * u**3 - 15 * u**4 + 6 * u**5)
    ds = distance / duration * (30 * u**2 - 60 * u**3 + 30 * u**4)
    dds = distance / duration**2 * (60 * u - 180 * u**2 + 120 * u**3)
    inside = (t >= 0.0) & (t <= duration)
    return s, np.where(inside, ds, 0.0), np.where(inside, dds, 0.0)


def transfer_track(start_ned: ArrayLike, end_ned: ArrayLike, speed: float, yaw_ned: float,
                   rate: float) -> SetpointTrack:
    """From `start_ned` to `end_ned` at rest: vertical segment first, then horizontal.

    Each segment is a quintic whose peak speed is `speed` (peak = 1.875 * distance / T).
    This is the climb from home to the plan's start; it is not deconflicted between vehicles,
    which is why homes should lie below the starts.
    """
    _check_rate(rate)
    if speed <= 0.0:
        raise ValueError("speed must be positive")
    start = np.asarray(start_ned, dtype=float)
    end = np.asarray(end_ned, dtype=float)
    mid = np.array([start[0], start[1], end[2]])
    segments = [(start, mid), (mid, end)]
    positions, velocities, accelerations = [], [], []
    for a, b in segments:
        delta = b - a
        dist = float(np.linalg.norm(delta))
        duration = 1.875 * dist / speed
        ticks = int(np.ceil(duration * rate)) + 1
        t = np.arange(ticks) / rate
        s, ds, dds = _quintic(dist, duration, t)
        unit = delta / dist if dist > 0 else np.zeros(3)
        positions.append(a + s[:, None] * unit)
        velocities.append(ds[:, None] * unit)
        accelerations.append(dds[:, None] * unit)
    return SetpointTrack(np.concatenate(positions), np.concatenate(velocities),
                         np.concatenate(accelerations), yaw_ned, rate)


def _check_rate(rate: float) -> None:
    if not 0.0 < rate <= MAX_RATE_HZ:
        raise ValueError(f"stream rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate:g}")
