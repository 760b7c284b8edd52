"""How a mock vehicle encodes each message it sends, from its state (`VehicleState`).

Long: a table of encoders, one short function per message the mock sends.

Every encoder is a function (state, mock time s) -> message (None: nothing this time). Values
come from the vehicle's model, so the fast streams are plausible (attitude from the commanded
acceleration), not sensor-accurate. Which of them go out, and how often, is
`gcs.sim.telemetry`; the vehicle packs (numbers, signs) what these build.
"""

from __future__ import annotations

import math
import struct
import time
from typing import Any, ClassVar, Protocol

import numpy as np

from gcs import frames
from gcs.autopilot import ardupilot, px4
from gcs.sim.config import MockConfig, MockFaults
from gcs.sim.model import GRAVITY, FleetModel
from gcs.wire import mavlink, time_boot_ms

__all__ = [
    "CAPABILITIES",
    "ENCODER",
    "PROTOCOL_VERSION_ID",
    "ProtocolVersionMessage",
    "VehicleState",
    "altitude",
    "attitude",
    "attitude_quaternion",
    "attitude_target",
    "autopilot_version",
    "battery_status",
    "estimator_status",
    "extended_sys_state",
    "global_position",
    "gps_global_origin",
    "gps_raw",
    "heartbeat",
    "highres_imu",
    "home_position",
    "local_position",
    "odometry",
    "position_target_global",
    "position_target_local",
    "protocol_version",
    "scaled_pressure",
    "servo_output",
    "sys_status",
    "system_time",
    "timesync",
    "vfr_hud",
    "vibration",
]

#: Builds message objects only (encoding carries no state): each vehicle packs them with its
#: own pymavlink instance, which numbers and signs them.
ENCODER = mavlink.MAVLink(None)


class VehicleState(Protocol):
    """What the encoders read of a vehicle (`gcs.sim.vehicle.MockVehicle` has it)."""

    @property
    def index(self) -> int: ...
    @property
    def system_id(self) -> int: ...
    @property
    def model(self) -> FleetModel: ...
    @property
    def config(self) -> MockConfig: ...
    @property
    def faults(self) -> MockFaults: ...
    @property
    def mode(self) -> px4.Px4Mode: ...
    @property
    def armed(self) -> bool: ...
    @property
    def in_air(self) -> bool: ...
    @property
    def failsafe(self) -> bool: ...
    @property
    def terminated(self) -> bool: ...
    @property
    def yaw(self) -> float: ...
    @property
    def battery(self) -> float: ...
    @property
    def home_world(self) -> np.ndarray: ...
    @property
    def world_origin(self) -> frames.Geodetic: ...
    @property
    def origin(self) -> frames.Geodetic: ...
    @property
    def fence_breached(self) -> bool: ...


_m = mavlink
_SENSORS = (
    _m.MAV_SYS_STATUS_SENSOR_3D_GYRO | _m.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | _m.MAV_SYS_STATUS_SENSOR_3D_MAG | _m.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | _m.MAV_SYS_STATUS_SENSOR_GPS | _m.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | _m.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | _m.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | _m.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | _m.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | _m.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | _m.MAV_SYS_STATUS_AHRS
    | _m.MAV_SYS_STATUS_SENSOR_BATTERY | _m.MAV_SYS_STATUS_GEOFENCE
)
_PREARM = _m.MAV_SYS_STATUS_PREARM_CHECK
#: PX4 v1.16.0 release: major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE_OFFICIAL
_PX4_VERSION = (1 << 24) | (16 << 16) | (0 << 8) | 255


# ------------------------------------------------------------------------ shared shapes
# Attitude from the acceleration the model achieves (a quadrotor tilts its thrust vector),
# quaternion from roll/pitch/yaw.


def _attitude(v: VehicleState) -> tuple[float, float, float]:
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


def _geodetic_now(v: VehicleState) -> frames.Geodetic:
    offset = frames.ned_vector_to_world(v.model.position[v.index])
    return frames.enu_to_geodetic(v.home_world + offset, v.world_origin)


def _remaining(v: VehicleState) -> float:
    return v.battery if v.faults.battery is None else v.faults.battery


# ----------------------------------------------------------------------------- status


def heartbeat(v: VehicleState, now: float) -> Any:
    """HEARTBEAT: PX4 (or ArduCopter: `gcs.sim.arducopter`) quadrotor, custom mode, armed
    flag; MAV_STATE says failsafe/termination."""
    base = _m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | _m.MAV_MODE_FLAG_STABILIZE_ENABLED
    kind = _m.MAV_AUTOPILOT_PX4
    if isinstance(v.mode, ardupilot.CopterMode):
        kind = _m.MAV_AUTOPILOT_ARDUPILOTMEGA
        if v.mode == ardupilot.GUIDED:
            base |= _m.MAV_MODE_FLAG_GUIDED_ENABLED
    elif v.mode.main in (px4.MainMode.AUTO, px4.MainMode.OFFBOARD):
        base |= _m.MAV_MODE_FLAG_AUTO_ENABLED | _m.MAV_MODE_FLAG_GUIDED_ENABLED
    elif v.mode.main == px4.MainMode.POSCTL:
        base |= _m.MAV_MODE_FLAG_GUIDED_ENABLED | _m.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    if v.armed:
        base |= _m.MAV_MODE_FLAG_SAFETY_ARMED
    state = (_m.MAV_STATE_FLIGHT_TERMINATION if v.terminated else
             _m.MAV_STATE_CRITICAL if v.failsafe else
             _m.MAV_STATE_ACTIVE if v.armed else _m.MAV_STATE_STANDBY)
    return ENCODER.heartbeat_encode(_m.MAV_TYPE_QUADROTOR, kind, base, v.mode.custom_mode,
                                    state)


def sys_status(v: VehicleState, now: float) -> Any:
    """SYS_STATUS: sensors present and enabled, healthy unless injected; pre-arm once settled;
    the geofence present, enabled and healthy unless breached (as PX4 reports it)."""
    settled = now >= v.config.settle_time
    present = _SENSORS | _PREARM
    health = (_SENSORS | (_PREARM if settled or v.armed else 0)) & ~v.faults.unhealthy
    if v.fence_breached:
        health &= ~_m.MAV_SYS_STATUS_GEOFENCE
    remaining = _remaining(v)
    voltage = round(1000 * (13.2 + 3.6 * remaining / 100.0))  # 4S: 13.2 V empty, 16.8 full
    return ENCODER.sys_status_encode(present, present, health, 250, voltage, 1200,
                                     round(remaining), 0, 0, 0, 0, 0, 0)


def extended_sys_state(v: VehicleState, now: float) -> Any:
    landed = (_m.MAV_LANDED_STATE_ON_GROUND if not v.in_air else
              _m.MAV_LANDED_STATE_LANDING if v.mode in (px4.LAND, ardupilot.LAND) else
              _m.MAV_LANDED_STATE_IN_AIR)
    return ENCODER.extended_sys_state_encode(0, landed)


#: What the mock implements, as AUTOPILOT_VERSION capability bits: MAVLink 2 (with signing),
#: COMMAND_INT, SET_POSITION_TARGET_LOCAL_NED, the mission protocol with MISSION_ITEM_INT for
#: missions, fences and rally points, and parameters encoded byte-wise as PX4 does. Not
#: SET_ATTITUDE_TARGET, global setpoints, MAVFTP or terrain.
CAPABILITIES = (_m.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | _m.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | _m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | _m.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | _m.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | _m.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
                | _m.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE)


def autopilot_version(v: VehicleState, now: float) -> Any:
    """AUTOPILOT_VERSION: PX4 v1.16.0's version, the mock's `CAPABILITIES`."""
    caps = CAPABILITIES
    return ENCODER.autopilot_version_encode(
        caps, _PX4_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, v.system_id)


# --------------------------------------------------------------------------- position


def local_position(v: VehicleState, now: float) -> Any:
    """LOCAL_POSITION_NED (NaN with `MockFaults.nan_position`)."""
    p, vel = v.model.position[v.index], v.model.velocity[v.index]
    if v.faults.nan_position:
        p = vel = (math.nan, math.nan, math.nan)
    return ENCODER.local_position_ned_encode(time_boot_ms(now), p[0], p[1], p[2],
                                             vel[0], vel[1], vel[2])


def global_position(v: VehicleState, now: float) -> Any:
    g = _geodetic_now(v)
    vel = v.model.velocity[v.index]
    heading = int(math.degrees(v.yaw) % 360.0 * 100)
    return ENCODER.global_position_int_encode(
        time_boot_ms(now), round(g.lat * 1e7), round(g.lon * 1e7), round(g.alt * 1000),
        round(-v.model.position[v.index, 2] * 1000), round(vel[0] * 100),
        round(vel[1] * 100), round(vel[2] * 100), heading)


def gps_raw(v: VehicleState, now: float) -> Any:
    """GPS_RAW_INT: fix (3 unless injected) and the estimate noise's accuracy."""
    g = _geodetic_now(v)
    fix = 3 if v.faults.gps_fix is None else v.faults.gps_fix
    noise = v.config.estimate_noise
    h_acc, v_acc = (50, 80) if noise is None else (  # mm: ideal, or the noise's 1 sigma
        round(noise.horizontal_accuracy * 1000), round(noise.vertical_accuracy * 1000))
    return ENCODER.gps_raw_int_encode(
        int(now * 1e6), fix, round(g.lat * 1e7), round(g.lon * 1e7), round(g.alt * 1000),
        80, 120, 0, 0, 12 if fix >= 3 else 0, 0, h_acc, v_acc, 100, 0, 0)


def home_position(v: VehicleState, now: float) -> Any:
    o = v.origin
    return ENCODER.home_position_encode(
        round(o.lat * 1e7), round(o.lon * 1e7), round(o.alt * 1000), 0.0, 0.0, 0.0,
        [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, int(now * 1e6))


def gps_global_origin(v: VehicleState, now: float) -> Any:
    o = v.origin
    return ENCODER.gps_global_origin_encode(
        round(o.lat * 1e7), round(o.lon * 1e7), round(o.alt * 1000), int(now * 1e6))


def odometry(v: VehicleState, now: float) -> Any:
    p, vel = v.model.position[v.index], v.model.velocity[v.index]
    return ENCODER.odometry_encode(
        int(now * 1e6), _m.MAV_FRAME_LOCAL_NED, _m.MAV_FRAME_BODY_FRD,
        p[0], p[1], p[2], _quaternion(*_attitude(v)), vel[0], vel[1], vel[2],
        0.0, 0.0, 0.0, [math.nan] * 21, [math.nan] * 21, 0, _m.MAV_ESTIMATOR_TYPE_VIO)


def altitude(v: VehicleState, now: float) -> Any:
    up = -float(v.model.position[v.index, 2])
    amsl = v.origin.alt + up
    return ENCODER.altitude_encode(int(now * 1e6), amsl, amsl, up, up, math.nan, math.nan)


def vfr_hud(v: VehicleState, now: float) -> Any:
    vel = v.model.velocity[v.index]
    speed = math.hypot(vel[0], vel[1])
    heading = round(math.degrees(v.yaw) % 360.0)
    return ENCODER.vfr_hud_encode(speed, speed, heading, 50 if v.armed else 0,
                                  v.origin.alt - float(v.model.position[v.index, 2]), -vel[2])


# --------------------------------------------------------------------------- attitude


def attitude(v: VehicleState, now: float) -> Any:
    roll, pitch, yaw = _attitude(v)
    return ENCODER.attitude_encode(time_boot_ms(now), roll, pitch, yaw, 0.0, 0.0, 0.0)


def attitude_quaternion(v: VehicleState, now: float) -> Any:
    return ENCODER.attitude_quaternion_encode(time_boot_ms(now), *_quaternion(*_attitude(v)),
                                              0.0, 0.0, 0.0)


def highres_imu(v: VehicleState, now: float) -> Any:
    a = v.model.acceleration[v.index]  # specific force in NED, body axes taken as level
    return ENCODER.highres_imu_encode(
        int(now * 1e6), a[0], a[1], a[2] - GRAVITY, 0.0, 0.0, 0.0, 0.21, 0.0, 0.43,
        1013.25, 0.0, v.origin.alt - v.model.position[v.index, 2], 25.0, 0x1FFF)


def attitude_target(v: VehicleState, now: float) -> Any:
    thrust = 0.5 if v.armed else 0.0
    return ENCODER.attitude_target_encode(time_boot_ms(now), 0, _quaternion(*_attitude(v)),
                                          0.0, 0.0, 0.0, thrust)


# ---------------------------------------------------------------------------- targets


def position_target_local(v: VehicleState, now: float) -> Any:
    m, i = v.model, v.index
    p, vel, acc = m.position_sp[i], m.velocity_sp[i], m.acceleration_sp[i]
    return ENCODER.position_target_local_ned_encode(
        time_boot_ms(now), _m.MAV_FRAME_LOCAL_NED, 0, p[0], p[1], p[2],
        vel[0], vel[1], vel[2], acc[0], acc[1], acc[2], v.yaw, 0.0)


def position_target_global(v: VehicleState, now: float) -> Any:
    o = v.origin
    m, i = v.model, v.index
    vel, acc = m.velocity_sp[i], m.acceleration_sp[i]
    return ENCODER.position_target_global_int_encode(
        time_boot_ms(now), _m.MAV_FRAME_GLOBAL_INT, 0, round(o.lat * 1e7),
        round(o.lon * 1e7), o.alt - float(m.position_sp[i, 2]), vel[0], vel[1], vel[2],
        acc[0], acc[1], acc[2], v.yaw, 0.0)


# ------------------------------------------------------------------------ the others


def servo_output(v: VehicleState, now: float) -> Any:
    pwm = 1500 if v.armed else 900
    return ENCODER.servo_output_raw_encode(int(now * 1e6) & 0xFFFFFFFF, 0, pwm, pwm, pwm, pwm,
                                           0, 0, 0, 0)


def timesync(v: VehicleState, now: float) -> Any:
    return ENCODER.timesync_encode(0, int(now * 1e9))  # PX4 asks; the GCS need not answer


def scaled_pressure(v: VehicleState, now: float) -> Any:
    return ENCODER.scaled_pressure_encode(time_boot_ms(now), 1013.25, 0.0, 2500)


def estimator_status(v: VehicleState, now: float) -> Any:
    flags = (_m.ESTIMATOR_ATTITUDE | _m.ESTIMATOR_VELOCITY_HORIZ
             | _m.ESTIMATOR_VELOCITY_VERT | _m.ESTIMATOR_POS_HORIZ_REL
             | _m.ESTIMATOR_POS_HORIZ_ABS | _m.ESTIMATOR_POS_VERT_ABS)
    return ENCODER.estimator_status_encode(int(now * 1e6), flags, 0.1, 0.1, 0.1, 0.1, 0.0, 0.0,
                                           0.5, 0.8)


def system_time(v: VehicleState, now: float) -> Any:
    return ENCODER.system_time_encode(int(time.time() * 1e6), time_boot_ms(now))


def battery_status(v: VehicleState, now: float) -> Any:
    remaining = _remaining(v)
    cell = round(1000 * (3.3 + 0.9 * remaining / 100.0))
    return ENCODER.battery_status_encode(0, _m.MAV_BATTERY_FUNCTION_ALL,
                                         _m.MAV_BATTERY_TYPE_LIPO, 2500,
                                         [cell] * 4 + [0xFFFF] * 6, 1200, -1, -1,
                                         round(remaining))


#: PROTOCOL_VERSION's message id; pymavlink's common dialect does not define the message.
PROTOCOL_VERSION_ID = 300


_MESSAGE: Any = _m.MAVLink_message  # pymavlink's base class of every message


class ProtocolVersionMessage(_MESSAGE):  # type: ignore[misc]  # pymavlink has no types
    """PROTOCOL_VERSION (300) from MAVLink's common.xml, which pymavlink's generated dialect
    leaves out: version, min_version, max_version (uint16, 100 x the MAVLink version), then
    the 8-byte hashes of the spec and the library (zeros: not known)."""

    id = PROTOCOL_VERSION_ID
    msgname = "PROTOCOL_VERSION"
    fieldnames: ClassVar[list[str]] = ["version", "min_version", "max_version",
                                       "spec_version_hash", "library_version_hash"]
    ordered_fieldnames: ClassVar[list[str]] = fieldnames
    crc_extra = 217
    """x25 over the message's name and fields, as mavgen computes it."""
    unpacker = struct.Struct("<HHH8s8s")

    def __init__(self, version: int, min_version: int, max_version: int) -> None:
        _MESSAGE.__init__(self, PROTOCOL_VERSION_ID, self.msgname)
        self._fieldnames = self.fieldnames
        self.version, self.min_version, self.max_version = version, min_version, max_version
        self.spec_version_hash = self.library_version_hash = bytes(8)

    def pack(self, mav: Any, force_mavlink1: bool = False) -> bytes:
        payload = self.unpacker.pack(self.version, self.min_version, self.max_version,
                                     self.spec_version_hash, self.library_version_hash)
        return bytes(self._pack(mav, self.crc_extra, payload, force_mavlink1=force_mavlink1))


def protocol_version(v: VehicleState, now: float) -> Any:
    """PROTOCOL_VERSION: MAVLink 2 (200), speaking 1 (100) to 2, as PX4 answers it."""
    return ProtocolVersionMessage(200, 100, 200)


def vibration(v: VehicleState, now: float) -> Any:
    return ENCODER.vibration_encode(int(now * 1e6), 0.01, 0.01, 0.01, 0, 0, 0)
