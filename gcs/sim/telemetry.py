"""What a mock vehicle sends on its offboard link, and how often: one table (`STREAMS`).

Two profiles (`MockConfig.telemetry_profile`):

- ``minimal`` (the default): the mock's own set at `MockConfig`'s rates (HEARTBEAT,
  SYS_STATUS and EXTENDED_SYS_STATE at `status_rate`, LOCAL_POSITION_NED at `position_rate`,
  ATTITUDE at `attitude_rate`, GLOBAL_POSITION_INT at `global_position_rate`, GPS_RAW_INT at
  `gps_rate`, HOME_POSITION every 5 s): about 65 messages/s per vehicle.
- ``px4``: PX4's offboard/API link (UDP `gcs.autopilot.px4.OFFBOARD_GCS_BASE_PORT` + i, MAVLink mode
  "onboard" in PX4's mavlink_main.cpp) as measured on PX4 v1.16 SITL: ATTITUDE 100/s; HIGHRES_IMU,
  ATTITUDE_QUATERNION, GLOBAL_POSITION_INT 50/s; LOCAL_POSITION_NED and ODOMETRY 30/s;
  GPS_RAW_INT 8/s; SYS_STATUS 5/s; a dozen more at 0.5-10/s: about 410 messages/s (24 KB/s).

Every id of the table is a *stream* in PX4's sense: MAV_CMD_SET_MESSAGE_INTERVAL can change
its rate, stop it (-1) or restore its default (0), in either profile (a ``minimal`` vehicle
starts the px4-only streams on request, at rate 0 by default). HEARTBEAT is refused, like
PX4's `MavlinkReceiver::set_message_interval`; an id with no stream is refused (FAILED).
What each message carries is `gcs.sim.messages`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from gcs.sim import messages as msg
from gcs.sim.config import MockConfig
from gcs.sim.messages import VehicleState
from gcs.wire import mavlink

__all__ = ["BY_ID", "PROFILES", "STREAMS", "Builder", "Stream", "default_rates", "message_name"]

#: Telemetry profiles of the mock (`MockConfig.telemetry_profile`).
PROFILES = ("minimal", "px4")

Builder = Callable[[VehicleState, float], Any]
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


def _heartbeat_stream(v: VehicleState, now: float) -> Any:
    """HEARTBEAT, unless `MockFaults.heartbeats` stopped it."""
    return msg.heartbeat(v, now) if v.faults.heartbeats else None


_m = mavlink
#: The offboard link's streams (the order is the send order within one mock tick).
STREAMS: tuple[Stream, ...] = (
    Stream(_m.MAVLINK_MSG_ID_HEARTBEAT, 1.0, "status_rate", _heartbeat_stream),
    Stream(_m.MAVLINK_MSG_ID_SYS_STATUS, 5.0, "status_rate", msg.sys_status),
    Stream(_m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 5.0, "status_rate", msg.extended_sys_state),
    Stream(_m.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 30.0, "position_rate", msg.local_position),
    Stream(_m.MAVLINK_MSG_ID_ATTITUDE, 100.0, "attitude_rate", msg.attitude),
    Stream(_m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 50.0, "global_position_rate",
           msg.global_position),
    Stream(_m.MAVLINK_MSG_ID_GPS_RAW_INT, 8.0, "gps_rate", msg.gps_raw),
    Stream(_m.MAVLINK_MSG_ID_HOME_POSITION, 0.5, "0.2", msg.home_position),
    Stream(_m.MAVLINK_MSG_ID_HIGHRES_IMU, 50.0, None, msg.highres_imu),
    Stream(_m.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 50.0, None, msg.attitude_quaternion),
    Stream(_m.MAVLINK_MSG_ID_ODOMETRY, 30.0, None, msg.odometry),
    Stream(_m.MAVLINK_MSG_ID_ALTITUDE, 10.0, None, msg.altitude),
    Stream(_m.MAVLINK_MSG_ID_ATTITUDE_TARGET, 10.0, None, msg.attitude_target),
    Stream(_m.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED, 10.0, None, msg.position_target_local),
    Stream(_m.MAVLINK_MSG_ID_POSITION_TARGET_GLOBAL_INT, 10.0, None, msg.position_target_global),
    Stream(_m.MAVLINK_MSG_ID_VFR_HUD, 10.0, None, msg.vfr_hud),
    Stream(_m.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 10.0, None, msg.servo_output),
    Stream(_m.MAVLINK_MSG_ID_TIMESYNC, 10.0, None, msg.timesync),
    Stream(_m.MAVLINK_MSG_ID_SCALED_PRESSURE, 10.0, None, msg.scaled_pressure),
    Stream(_m.MAVLINK_MSG_ID_ESTIMATOR_STATUS, 1.0, None, msg.estimator_status),
    Stream(_m.MAVLINK_MSG_ID_SYSTEM_TIME, 1.0, None, msg.system_time),
    Stream(_m.MAVLINK_MSG_ID_BATTERY_STATUS, 0.5, None, msg.battery_status),
    Stream(_m.MAVLINK_MSG_ID_VIBRATION, 0.5, None, msg.vibration),
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
