"""COMMAND_LONG and COMMAND_INT on a mock vehicle, answered as PX4's commander answers them.

Arming is TEMPORARILY_REJECTED during `settle_time` after start (with PX4's "Preflight Fail"
and "Arming denied" texts), DENIED after a flight termination or with an injected refusal;
disarming in the air is DENIED unless forced. OFFBOARD is refused (TEMPORARILY_REJECTED)
unless a setpoint arrived within COM_OF_LOSS_T; Position mode unless manual control input
(MANUAL_CONTROL) arrived within COM_RC_LOSS_T, with commander's "Switching to Position is
currently not available". MAV_CMD_NAV_TAKEOFF enters AUTO.TAKEOFF and MAV_CMD_NAV_RETURN_TO_LAUNCH
AUTO.RTL (`gcs.sim.automodes`). MAV_CMD_REQUEST_PROTOCOL_VERSION and REQUEST_MESSAGE 300 answer
PROTOCOL_VERSION. DO_SET_MODE and REQUEST_MESSAGE are ACKed twice, like PX4 does.
MAV_CMD_DO_FLIGHTTERMINATION stops the motors (it falls); arming is then denied. Unknown
commands are UNSUPPORTED.
"""

from __future__ import annotations

from typing import Any

from gcs.autopilot import px4
from gcs.sim import automodes, messages
from gcs.sim.core import VehicleCore
from gcs.wire import addressed_to, mavlink

__all__ = ["handle_command", "requested_message"]

_m = mavlink
#: REQUEST_MESSAGE: what the mock answers, by message id.
_REQUESTABLE = {
    _m.MAVLINK_MSG_ID_AUTOPILOT_VERSION: messages.autopilot_version,
    _m.MAVLINK_MSG_ID_HOME_POSITION: messages.home_position,
    _m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: messages.gps_global_origin,
    _m.MAVLINK_MSG_ID_HEARTBEAT: messages.heartbeat,
    _m.MAVLINK_MSG_ID_SYS_STATUS: messages.sys_status,
    messages.PROTOCOL_VERSION_ID: messages.protocol_version,
}


def requested_message(v: VehicleCore, message_id: int, now: float) -> Any:
    """The reply to MAV_CMD_REQUEST_MESSAGE for `message_id` (None: not supported)."""
    encode = _REQUESTABLE.get(message_id)
    return encode(v, now) if encode is not None else None


def handle_command(v: VehicleCore, msg: Any) -> None:
    """Carry out a COMMAND_LONG or COMMAND_INT addressed to `v` and ACK it."""
    if not addressed_to(msg, v.system_id, v.component_id):
        return
    cmd = msg.command
    p1, p2, p3 = msg.param1, msg.param2, msg.param3
    now = v.now()
    if cmd == _m.MAV_CMD_COMPONENT_ARM_DISARM:
        if p1 >= 0.5:
            _arm(v, msg, now)
        elif not v.armed or not v.in_air or p2 == px4.DISARM_FORCE_MAGIC:
            v.disarm("external command")
            v.in_air = False
            v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
        else:
            v.statustext(_m.MAV_SEVERITY_CRITICAL, "Disarming denied: not landed")
            v.ack(msg, cmd, _m.MAV_RESULT_DENIED)
    elif cmd == _m.MAV_CMD_DO_SET_MODE:
        result = _set_mode(v, int(p1), round(p2), round(p3), now)
        v.ack(msg, cmd, result, times=2)
    elif cmd == _m.MAV_CMD_DO_FLIGHTTERMINATION and p1 >= 0.5:
        v.terminated = True
        v.disarm("flight termination")
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_NAV_LAND:
        v.set_mode(px4.LAND)
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_NAV_TAKEOFF:
        v.auto.takeoff_height = automodes.takeoff_height(v, msg.z if _is_int(msg) else
                                                         msg.param7)
        if v.mode == px4.TAKEOFF:
            automodes.enter(v, px4.TAKEOFF)
        else:
            v.set_mode(px4.TAKEOFF)
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        v.set_mode(px4.RTL)
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_REQUEST_PROTOCOL_VERSION:
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
        v.reply(messages.protocol_version(v, now))
    elif cmd == _m.MAV_CMD_REQUEST_MESSAGE:
        reply = requested_message(v, round(p1), now)
        result = _m.MAV_RESULT_ACCEPTED if reply is not None else _m.MAV_RESULT_UNSUPPORTED
        v.ack(msg, cmd, result, times=2 if reply is not None else 1)
        if reply is not None:
            v.reply(reply)
    elif cmd == _m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
        v.reply(messages.autopilot_version(v, now))
    elif cmd == _m.MAV_CMD_SET_MESSAGE_INTERVAL:
        v.ack(msg, cmd, v.set_interval(round(p1), p2))
    elif cmd == _m.MAV_CMD_GET_HOME_POSITION:
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
        v.reply(messages.home_position(v, now))
    else:
        v.ack(msg, cmd, _m.MAV_RESULT_UNSUPPORTED)


def _is_int(msg: Any) -> bool:
    """COMMAND_INT (param7 is its field z)."""
    return bool(msg.get_type() == "COMMAND_INT")


def _arm(v: VehicleCore, msg: Any, now: float) -> None:
    cmd = _m.MAV_CMD_COMPONENT_ARM_DISARM
    if v.armed:
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif v.terminated:
        v.statustext(_m.MAV_SEVERITY_CRITICAL, "Arming denied: flight terminated")
        v.ack(msg, cmd, _m.MAV_RESULT_DENIED)
    elif v.faults.refuse_arming:
        v.statustext(_m.MAV_SEVERITY_CRITICAL, "Arming denied: injected fault")
        v.ack(msg, cmd, _m.MAV_RESULT_DENIED)
    elif now < v.config.settle_time:  # PX4: the failed check, then the denial
        v.statustext(_m.MAV_SEVERITY_CRITICAL, "Preflight Fail: heading estimate not stable")
        v.statustext(_m.MAV_SEVERITY_CRITICAL,
                     "Arming denied: Resolve system health failures first")
        v.ack(msg, cmd, _m.MAV_RESULT_TEMPORARILY_REJECTED)
    else:
        v.arm()
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)


def _set_mode(v: VehicleCore, base_mode: int, main: int, sub: int, now: float) -> int:
    if not base_mode & _m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return _m.MAV_RESULT_UNSUPPORTED
    wanted = px4.Px4Mode(main, sub if main == px4.MainMode.AUTO else 0)
    if wanted == px4.OFFBOARD:
        if now - v.last_setpoint_time > v.config.offboard_loss_timeout:
            v.statustext(_m.MAV_SEVERITY_CRITICAL,
                         "Switching to Offboard is currently not available")
            return _m.MAV_RESULT_TEMPORARILY_REJECTED
        v.set_mode(px4.OFFBOARD)
        # hold where it is until the next setpoint arrives (PX4 only uses setpoints
        # received while in OFFBOARD)
        v.model.hold(v.index, v.model.position[v.index].copy())
        return _m.MAV_RESULT_ACCEPTED
    if wanted == px4.POSITION and (now - v.last_manual_control
                                   > v.config.manual_control_timeout):
        v.statustext(_m.MAV_SEVERITY_CRITICAL,
                     "Switching to Position is currently not available")
        return _m.MAV_RESULT_TEMPORARILY_REJECTED
    if wanted in (px4.HOLD, px4.LAND, px4.POSITION, px4.RTL, px4.TAKEOFF):
        v.set_mode(wanted)
        return _m.MAV_RESULT_ACCEPTED
    v.statustext(_m.MAV_SEVERITY_CRITICAL, f"Mode {wanted.name} not supported")
    return _m.MAV_RESULT_TEMPORARILY_REJECTED
