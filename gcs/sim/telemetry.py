"""What a mock vehicle sends on its offboard link, and how often: one table (`STREAMS`).

Two profiles (`MockConfig.telemetry_profile`):

- ``minimal`` (the default): the mock's historical set at `MockConfig`'s rates (HEARTBEAT,
  SYS_STATUS and EXTENDED_SYS_STATE at `status_rate`, LOCAL_POSITION_NED at `position_rate`,
  ATTITUDE at `attitude_rate`, GLOBAL_POSITION_INT at `global_position_rate`, GPS_RAW_INT at
  `gps_rate`, HOME_POSITION every 5 s): about 65 messages/s per vehicle.
- ``px4``: PX4's offboard/API link (UDP 14540 + i, MAVLink mode "onboard" in PX4's
  mavlink_main.cpp) as measured on PX4 v1.16 SITL: ATTITUDE 100/s; HIGHRES_IMU,
  ATTITUDE_QUATERNION, GLOBAL_POSITION_INT 50/s; LOCAL_POSITION_NED and ODOMETRY 30/s;
  GPS_RAW_INT 8/s; SYS_STATUS 5/s; a dozen more at 0.5-10/s: about 410 messages/s (24 KB/s).

Every id of the table is a *stream* in PX4's sense: MAV_CMD_SET_MESSAGE_INTERVAL can change
its rate, stop it (-1) or restore its default (0), in either profile (a ``minimal`` vehicle
starts the px4-only streams on request, at rate 0 by default). HEARTBEAT is refused, like
PX4's `MavlinkReceiver::set_message_interval`; an id with no stream is refused (FAILED).
The builders say what each message carries; values come from the vehicle's model, so the
fast streams are plausible (attitude from the commanded acceleration), not sensor-accurate.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gcs import px4
from gcs.sim.model import GRAVITY
from gcs.wire import mavlink, time_boot_ms

if TYPE_CHECKING:
    from gcs.sim.vehicle import MockConfig, MockVehicle

__all__ = ["PROFILES", "STREAMS", "Stream", "default_rates", "message_name"]

#: Telemetry profiles of the mock (`MockConfig.telemetry_profile`).
PROFILES = ("minimal", "px4")

Builder = Callable[["MockVehicle", float], Any]
"""(vehicle, mock time s) -> the message to send (or None: nothing this time)."""


@dataclass(frozen=True)
class Stream:
    """One message stream of the offboard link."""

    msg_id: int
    px4_hz: float
    """PX4's default rate on the offboard link (Hz; measured on v1.16 SITL)."""
    minimal: str | None
    """``minimal`` profile: the `MockConfig` field holding its rate (Hz), a number as text
    for a fixed rate, or None when that profile does not send it."""
    build: Builder


def message_name(msg_id: int) -> str:
    """MAVLink message name of `msg_id` (the number as text if unknown to the dialect)."""
    entry = mavlink.mavlink_map.get(msg_id)
    return entry.msgname if entry is not None else str(msg_id)


# ----------------------------------------------------------------------------- builders
# Shared shapes: attitude from the acceleration the model achieves (a quadrotor tilts its
# thrust vector), quaternion from roll/pitch/yaw.


def _attitude(v: MockVehicle) -> tuple[float, float, float]:
    a = v.model.acceleration[v.index]
    c, s = math.cos(v.yaw), math.sin(v.yaw)
    forward, right = c * a[0] + s * a[1], -s * a[0] + c * a[1]
    thrust = max(GRAVITY - a[2], 0.1)
    return math.atan2(right, thrust), -math.atan2(forward, thrust), v.yaw


def _quaternion(roll: float, pitch: float, yaw: float) -> list[float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]


def _heartbeat(v: MockVehicle, now: float) -> Any:
    return v._heartbeat() if v.faults.heartbeats else None


def _local_position(v: MockVehicle, now: float) -> Any:
    p, vel = v.model.position[v.index], v.model.velocity[v.index]
    if v.faults.nan_position:
        p = vel = (math.nan, math.nan, math.nan)
    return v._mav.local_position_ned_encode(time_boot_ms(now), p[0], p[1], p[2],
                                            vel[0], vel[1], vel[2])


def _extended_sys_state(v: MockVehicle, now: float) -> Any:
    landed = (mavlink.MAV_LANDED_STATE_ON_GROUND if not v.in_air else
              mavlink.MAV_LANDED_STATE_LANDING if v.mode == px4.LAND else
              mavlink.MAV_LANDED_STATE_IN_AIR)
    return v._mav.extended_sys_state_encode(0, landed)


def _attitude_msg(v: MockVehicle, now: float) -> Any:
    roll, pitch, yaw = _attitude(v)
    return v._mav.attitude_encode(time_boot_ms(now), roll, pitch, yaw, 0.0, 0.0, 0.0)


def _attitude_quaternion(v: MockVehicle, now: float) -> Any:
    return v._mav.attitude_quaternion_encode(time_boot_ms(now), *_quaternion(*_attitude(v)),
                                             0.0, 0.0, 0.0)


def _highres_imu(v: MockVehicle, now: float) -> Any:
    a = v.model.acceleration[v.index]  # specific force in NED, body axes taken as level
    return v._mav.highres_imu_encode(
        int(now * 1e6), a[0], a[1], a[2] - GRAVITY, 0.0, 0.0, 0.0, 0.21, 0.0, 0.43,
        1013.25, 0.0, v.origin.alt - v.model.position[v.index, 2], 25.0, 0x1FFF)


def _odometry(v: MockVehicle, now: float) -> Any:
    p, vel = v.model.position[v.index], v.model.velocity[v.index]
    return v._mav.odometry_encode(
        int(now * 1e6), mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
        p[0], p[1], p[2], _quaternion(*_attitude(v)), vel[0], vel[1], vel[2],
        0.0, 0.0, 0.0, [math.nan] * 21, [math.nan] * 21, 0, mavlink.MAV_ESTIMATOR_TYPE_VIO)


def _altitude(v: MockVehicle, now: float) -> Any:
    up = -float(v.model.position[v.index, 2])
    amsl = v.origin.alt + up
    return v._mav.altitude_encode(int(now * 1e6), amsl, amsl, up, up, math.nan, math.nan)


def _attitude_target(v: MockVehicle, now: float) -> Any:
    thrust = 0.5 if v.armed else 0.0
    return v._mav.attitude_target_encode(time_boot_ms(now), 0, _quaternion(*_attitude(v)),
                                         0.0, 0.0, 0.0, thrust)


def _position_target_local(v: MockVehicle, now: float) -> Any:
    m, i = v.model, v.index
    p, vel, acc = m.position_sp[i], m.velocity_sp[i], m.acceleration_sp[i]
    return v._mav.position_target_local_ned_encode(
        time_boot_ms(now), mavlink.MAV_FRAME_LOCAL_NED, 0, p[0], p[1], p[2],
        vel[0], vel[1], vel[2], acc[0], acc[1], acc[2], v.yaw, 0.0)


def _position_target_global(v: MockVehicle, now: float) -> Any:
    o = v.origin
    m, i = v.model, v.index
    vel, acc = m.velocity_sp[i], m.acceleration_sp[i]
    return v._mav.position_target_global_int_encode(
        time_boot_ms(now), mavlink.MAV_FRAME_GLOBAL_INT, 0, round(o.lat * 1e7),
        round(o.lon * 1e7), o.alt - float(m.position_sp[i, 2]), vel[0], vel[1], vel[2],
        acc[0], acc[1], acc[2], v.yaw, 0.0)


def _vfr_hud(v: MockVehicle, now: float) -> Any:
    vel = v.model.velocity[v.index]
    speed = math.hypot(vel[0], vel[1])
    heading = round(math.degrees(v.yaw) % 360.0)
    return v._mav.vfr_hud_encode(speed, speed, heading, 50 if v.armed else 0,
                                 v.origin.alt - float(v.model.position[v.index, 2]), -vel[2])


def _servo_output(v: MockVehicle, now: float) -> Any:
    pwm = 1500 if v.armed else 900
    return v._mav.servo_output_raw_encode(int(now * 1e6) & 0xFFFFFFFF, 0, pwm, pwm, pwm, pwm,
                                          0, 0, 0, 0)


def _timesync(v: MockVehicle, now: float) -> Any:
    return v._mav.timesync_encode(0, int(now * 1e9))  # PX4 asks; the GCS need not answer


def _scaled_pressure(v: MockVehicle, now: float) -> Any:
    return v._mav.scaled_pressure_encode(time_boot_ms(now), 1013.25, 0.0, 2500)


def _estimator_status(v: MockVehicle, now: float) -> Any:
    flags = (mavlink.ESTIMATOR_ATTITUDE | mavlink.ESTIMATOR_VELOCITY_HORIZ
             | mavlink.ESTIMATOR_VELOCITY_VERT | mavlink.ESTIMATOR_POS_HORIZ_REL
             | mavlink.ESTIMATOR_POS_HORIZ_ABS | mavlink.ESTIMATOR_POS_VERT_ABS)
    return v._mav.estimator_status_encode(int(now * 1e6), flags, 0.1, 0.1, 0.1, 0.1, 0.0, 0.0,
                                          0.5, 0.8)


def _system_time(v: MockVehicle, now: float) -> Any:
    return v._mav.system_time_encode(int(time.time() * 1e6), time_boot_ms(now))


def _battery_status(v: MockVehicle, now: float) -> Any:
    remaining = v.battery if v.faults.battery is None else v.faults.battery
    cell = round(1000 * (3.3 + 0.9 * remaining / 100.0))
    return v._mav.battery_status_encode(0, mavlink.MAV_BATTERY_FUNCTION_ALL,
                                        mavlink.MAV_BATTERY_TYPE_LIPO, 2500,
                                        [cell] * 4 + [0xFFFF] * 6, 1200, -1, -1,
                                        round(remaining))


def _vibration(v: MockVehicle, now: float) -> Any:
    return v._mav.vibration_encode(int(now * 1e6), 0.01, 0.01, 0.01, 0, 0, 0)


def _sys_status(v: MockVehicle, now: float) -> Any:
    return v._sys_status(now)


def _global_position(v: MockVehicle, now: float) -> Any:
    return v._global_position(now)


def _gps_raw(v: MockVehicle, now: float) -> Any:
    return v._gps_raw(now)


def _home_position(v: MockVehicle, now: float) -> Any:
    return v._home_position(now)


_m = mavlink
#: The offboard link's streams (the order is the send order within one mock tick).
STREAMS: tuple[Stream, ...] = (
    Stream(_m.MAVLINK_MSG_ID_HEARTBEAT, 1.0, "status_rate", _heartbeat),
    Stream(_m.MAVLINK_MSG_ID_SYS_STATUS, 5.0, "status_rate", _sys_status),
    Stream(_m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 5.0, "status_rate", _extended_sys_state),
    Stream(_m.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 30.0, "position_rate", _local_position),
    Stream(_m.MAVLINK_MSG_ID_ATTITUDE, 100.0, "attitude_rate", _attitude_msg),
    Stream(_m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 50.0, "global_position_rate",
           _global_position),
    Stream(_m.MAVLINK_MSG_ID_GPS_RAW_INT, 8.0, "gps_rate", _gps_raw),
    Stream(_m.MAVLINK_MSG_ID_HOME_POSITION, 0.5, "0.2", _home_position),
    Stream(_m.MAVLINK_MSG_ID_HIGHRES_IMU, 50.0, None, _highres_imu),
    Stream(_m.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 50.0, None, _attitude_quaternion),
    Stream(_m.MAVLINK_MSG_ID_ODOMETRY, 30.0, None, _odometry),
    Stream(_m.MAVLINK_MSG_ID_ALTITUDE, 10.0, None, _altitude),
    Stream(_m.MAVLINK_MSG_ID_ATTITUDE_TARGET, 10.0, None, _attitude_target),
    Stream(_m.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED, 10.0, None, _position_target_local),
    Stream(_m.MAVLINK_MSG_ID_POSITION_TARGET_GLOBAL_INT, 10.0, None, _position_target_global),
    Stream(_m.MAVLINK_MSG_ID_VFR_HUD, 10.0, None, _vfr_hud),
    Stream(_m.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 10.0, None, _servo_output),
    Stream(_m.MAVLINK_MSG_ID_TIMESYNC, 10.0, None, _timesync),
    Stream(_m.MAVLINK_MSG_ID_SCALED_PRESSURE, 10.0, None, _scaled_pressure),
    Stream(_m.MAVLINK_MSG_ID_ESTIMATOR_STATUS, 1.0, None, _estimator_status),
    Stream(_m.MAVLINK_MSG_ID_SYSTEM_TIME, 1.0, None, _system_time),
    Stream(_m.MAVLINK_MSG_ID_BATTERY_STATUS, 0.5, None, _battery_status),
    Stream(_m.MAVLINK_MSG_ID_VIBRATION, 0.5, None, _vibration),
)
#: The table by message id.
BY_ID: dict[int, Stream] = {s.msg_id: s for s in STREAMS}


def default_rates(config: MockConfig) -> dict[int, float]:
    """Each stream's default rate (Hz, 0 = not sent) under `config.telemetry_profile`.
    LOCAL_POSITION_NED follows `config.position_rate` in both profiles."""
    profile = config.telemetry_profile
    if profile not in PROFILES:
        raise ValueError(f"telemetry_profile must be one of {', '.join(PROFILES)}, "
                         f"got {profile!r}")
    rates = {}
    for s in STREAMS:
        if profile == "px4":
            hz = s.px4_hz
        elif s.minimal is None:
            hz = 0.0
        elif s.minimal[0].isdigit():
            hz = float(s.minimal)
        else:
            hz = float(getattr(config, s.minimal))
        rates[s.msg_id] = hz
    rates[mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED] = float(config.position_rate)
    return rates
