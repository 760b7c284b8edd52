"""Offboard setpoints on a mock vehicle: SET_POSITION_TARGET_LOCAL_NED taken as PX4's
mavlink_receiver takes it.

Taken only for target system = own id or 0 (component own or 0), frame MAV_FRAME_LOCAL_NED
(BODY_NED: velocity/acceleration only); IGNORE bits become NaN; a message with nothing left,
or with the FORCE bit and an acceleration, is ignored. Every accepted message is proof of life
for offboard, in any mode; only in OFFBOARD does it move the vehicle. A setpoint with a used
field (IGNORE bit clear) that is not finite, or beyond `SETPOINT_LIMITS` (absurd for a
quadrotor), is refused whole and counted in `setpoints_invalid`: the vehicle keeps its last
valid setpoint and the message is no proof of life. An ignored frame or FORCE bit is explained
in PX4's words (`refusal_text`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from gcs.wire import mavlink

__all__ = ["SETPOINT_LIMITS", "ReceivedSetpoint", "Refusal", "read_setpoint",
           "refusal_text", "setpoint_problem"]

# POSITION_TARGET_TYPEMASK bits (pymavlink's enum): X, Y, Z ignore are 1, 2, 4 times the
# first bit of each triple, and so on.
_IGNORE_X = mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
_IGNORE_VX = mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE
_IGNORE_AX = mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
_FORCE = mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET
_IGNORE_YAW = mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
_IGNORE_YAW_RATE = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE

#: Largest |component| of a used setpoint field the mock takes (LOCAL_NED, m, m/s, m/s^2):
#: far beyond any quadrotor, so only garbage is refused.
SETPOINT_LIMITS = {"position": 1e5, "velocity": 1e3, "acceleration": 1e3}

Vector = tuple[float, float, float]
#: Why a setpoint is not taken: "invalid" (`setpoint_problem`: refused, no proof of life) or
#: "ignored" (another frame, nothing usable, or FORCE with an acceleration).
Refusal = Literal["invalid", "ignored"]


@dataclass(frozen=True)
class ReceivedSetpoint:
    """A SET_POSITION_TARGET_LOCAL_NED the mock accepted (values after IGNORE -> NaN)."""

    time: float
    """Mock clock (s since start)."""
    time_boot_ms: int
    target_system: int
    target_component: int
    frame: int
    type_mask: int
    position: Vector
    velocity: Vector
    acceleration: Vector
    yaw: float


def setpoint_problem(msg: Any) -> str | None:
    """Why a SET_POSITION_TARGET_LOCAL_NED must be refused (a used field not finite or absurd),
    or None. Fields whose IGNORE bit is set are not looked at."""
    mask = msg.type_mask
    groups = (("position", _IGNORE_X, (msg.x, msg.y, msg.z)),
              ("velocity", _IGNORE_VX, (msg.vx, msg.vy, msg.vz)),
              ("acceleration", _IGNORE_AX, (msg.afx, msg.afy, msg.afz)))
    for name, first_bit, values in groups:
        for k, value in enumerate(values):
            if mask & (first_bit << k):
                continue
            if not math.isfinite(value):
                return f"{name} not finite"
            if abs(value) > SETPOINT_LIMITS[name]:
                return f"{name} beyond {SETPOINT_LIMITS[name]:g}"
    if not mask & _IGNORE_YAW and not math.isfinite(msg.yaw):
        return "yaw not finite"
    if not mask & _IGNORE_YAW_RATE and not math.isfinite(msg.yaw_rate):
        return "yaw_rate not finite"
    return None


def refusal_text(msg: Any) -> str | None:
    """PX4's STATUSTEXT (mavlink_receiver.cpp) for a setpoint ignored for its frame or for
    FORCE with an acceleration; None for the other reasons (PX4 is silent about them)."""
    if msg.coordinate_frame not in (mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_NED):
        return f"SET_POSITION_TARGET_LOCAL_NED coordinate frame {msg.coordinate_frame} unsupported"
    if msg.type_mask & _FORCE and (msg.type_mask & (_IGNORE_AX * 7)) != _IGNORE_AX * 7:
        return "SET_POSITION_TARGET_LOCAL_NED force not supported"
    return None


def _unused_to_nan(mask: int, first_bit: int, values: tuple[float, float, float]) -> Vector:
    x, y, z = (math.nan if mask & (first_bit << k) else float(values[k]) for k in range(3))
    return (x, y, z)


def _rotated(vector: Vector, yaw: float) -> Vector:
    """A BODY_NED vector in LOCAL_NED (all-NaN stays all-NaN; a NaN component counts as 0)."""
    if all(math.isnan(x) for x in vector):
        return vector
    c, s = math.cos(yaw), math.sin(yaw)
    x, y, z = (0.0 if math.isnan(e) else e for e in vector)
    return (c * x - s * y, s * x + c * y, z)


def read_setpoint(msg: Any, yaw: float, now: float) -> ReceivedSetpoint | Refusal:
    """A SET_POSITION_TARGET_LOCAL_NED as the vehicle takes it at mock time `now` (LOCAL_NED,
    unused fields NaN; a BODY_NED one rotated by the vehicle's `yaw`), or why it is not taken.
    The caller checks that it is addressed to the vehicle."""
    mask = msg.type_mask
    if setpoint_problem(msg) is not None:
        return "invalid"
    pos = _unused_to_nan(mask, _IGNORE_X, (msg.x, msg.y, msg.z))
    vel = _unused_to_nan(mask, _IGNORE_VX, (msg.vx, msg.vy, msg.vz))
    acc = _unused_to_nan(mask, _IGNORE_AX, (msg.afx, msg.afy, msg.afz))
    if msg.coordinate_frame == mavlink.MAV_FRAME_BODY_NED:
        pos, vel, acc = (math.nan, math.nan, math.nan), _rotated(vel, yaw), _rotated(acc, yaw)
    elif msg.coordinate_frame != mavlink.MAV_FRAME_LOCAL_NED:
        return "ignored"
    has_acc = not all(math.isnan(x) for x in acc)
    usable = has_acc or not all(math.isnan(x) for x in pos + vel)
    if not usable or (has_acc and mask & _FORCE):
        return "ignored"
    return ReceivedSetpoint(now, msg.time_boot_ms, msg.target_system, msg.target_component,
                            msg.coordinate_frame, mask, pos, vel, acc,
                            math.nan if mask & _IGNORE_YAW else msg.yaw)
