"""The mock's ArduCopter personality (`MockConfig.autopilot = "ardupilot"`): ArduCopter 4.7's rules
where they differ from PX4's, as ArduCopter SITL showed them (`gcs.autopilot.ardupilot`).

- HEARTBEAT: MAV_AUTOPILOT_ARDUPILOTMEGA, custom_mode the Copter mode number; it boots in
  STABILIZE and sends nothing else until streams are asked for (`gcs.sim.telemetry`);
- DO_SET_MODE (param2 = mode number, one ACK): GUIDED is accepted disarmed; unknown modes FAILED;
- arming: FAILED with "PreArm: Need Position Estimate" until `MockConfig.settle_time`;
  disarming in the air FAILED unless forced (21196);
- MAV_CMD_NAV_TAKEOFF (armed, GUIDED, on the ground) climbs to param7 m; position targets
  move it only in GUIDED once airborne, and are held for good when they stop, while a
  velocity feed-forward is flown on for GUID_TIMEOUT; a position target that arrives during
  the takeoff before it is airborne ends the takeoff and leaves it on the ground
  (`ModeGuided::set_destination` leaves the takeoff submode, and landed it flies nothing);
- LAND descends at LAND_SPEED (0.5 m/s) and disarms once down; RTL returns over home and lands;
  BRAKE holds where it is;
- the GCS failsafe: FS_GCS_ENABLE (0 by default) acts FS_GCS_TIMEOUT after the ground
  station's last HEARTBEAT (system MAV_GCS_SYSID);
- the fence acts only with FENCE_ENABLE = 1 (a breach lands: FENCE_ACTION's fallback);
- signed: unsigned RADIO_STATUS and RADIO only (its first serial port, which trusts everything,
  is not modelled: the mock's links are the GCS's other ports).
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from gcs.autopilot import ardupilot as ap
from gcs.sim.geofence import Geofence
from gcs.sim.model import FleetModel
from gcs.wire import addressed_to, mavlink

__all__ = ["BOOT_MODE", "UNSIGNED_ACCEPTED", "ArduHost", "ArduState", "follow",
           "handle_command", "heard", "is_command_handled", "set_mode", "tick"]

_m = mavlink
#: The mode ArduCopter boots in.
BOOT_MODE = ap.STABILIZE
#: Messages ArduPilot accepts unsigned on a signed port (GCS_Signing accept_unsigned_callback).
UNSIGNED_ACCEPTED = frozenset({_m.MAVLINK_MSG_ID_RADIO_STATUS, 166})  # 166: RADIO
#: Modes the mock takes (the rest are FAILED): those a GCS sets on a copter.
_MODES = frozenset({ap.CopterModeNumber.STABILIZE, ap.CopterModeNumber.ALT_HOLD,
                    ap.CopterModeNumber.GUIDED, ap.CopterModeNumber.LOITER,
                    ap.CopterModeNumber.RTL, ap.CopterModeNumber.LAND,
                    ap.CopterModeNumber.POSHOLD, ap.CopterModeNumber.BRAKE})
#: Commands this module answers; the rest are the shared handler's.
_COMMANDS = frozenset({_m.MAV_CMD_COMPONENT_ARM_DISARM, _m.MAV_CMD_DO_SET_MODE,
                       _m.MAV_CMD_NAV_TAKEOFF, _m.MAV_CMD_NAV_LAND,
                       _m.MAV_CMD_NAV_RETURN_TO_LAUNCH})
#: RTL lands once this close to home horizontally (m); the mock returns at its own height.
_RTL_REACHED_M = 0.3


class ArduState:
    """What the ArduCopter rules keep per vehicle."""

    def __init__(self) -> None:
        self.last_gcs_heartbeat = -math.inf
        """Mock time of the last HEARTBEAT from the ground station (system MAV_GCS_SYSID)."""
        self.gcs_failsafe = False
        self.landed_since: float | None = None
        self.guided_velocity = np.zeros(3)
        """The last position target's velocity feed-forward (flown on for GUID_TIMEOUT)."""
        self.guided_stopped = True
        """The feed-forward has been stopped (GUID_TIMEOUT passed, or none was given)."""
        self.taking_off = False
        """A MAV_CMD_NAV_TAKEOFF is climbing (until a mode change or a position target)."""


class ArduHost(Protocol):
    """What the rules need of a mock vehicle."""

    index: int
    system_id: int
    component_id: int
    mode: Any
    armed: bool
    in_air: bool
    terminated: bool
    fence_breached: bool
    last_setpoint_time: float
    ardu: ArduState
    geofence: Geofence

    @property
    def model(self) -> FleetModel: ...
    @property
    def params(self) -> Any: ...
    @property
    def config(self) -> Any: ...
    @property
    def position_ned(self) -> np.ndarray: ...
    def now(self) -> float: ...
    def event(self, what: str, at: float | None = None) -> None: ...
    def arm(self) -> None: ...
    def disarm(self, why: str) -> None: ...
    def statustext(self, severity: int, text: str) -> None: ...
    def ack(self, msg: Any, command: int, result: int, times: int = 1) -> None: ...


def set_mode(v: ArduHost, mode: ap.CopterMode) -> None:
    """Enter `mode`: LAND descends, RTL heads over home, every other mode holds here."""
    if mode == v.mode:
        return
    v.event(f"mode {v.mode.name} -> {mode.name}")
    v.mode = mode
    i = v.index
    v.ardu.landed_since = None
    v.ardu.taking_off = False
    if mode == ap.LAND:
        v.model.descend(i, ap.LAND_SPEED)
    elif mode == ap.RTL:
        v.model.hold(i, np.array([0.0, 0.0, v.model.position[i, 2]]))
    else:
        v.model.hold(i, v.model.position[i].copy())


def is_command_handled(command: int) -> bool:
    """Whether `handle_command` answers `command` (else the shared handler does)."""
    return command in _COMMANDS


def handle_command(v: ArduHost, msg: Any) -> None:
    """ArduCopter's answer to arming, mode, takeoff, land and RTL commands (one ACK each)."""
    if not addressed_to(msg, v.system_id, v.component_id):
        return
    cmd = msg.command
    if cmd == _m.MAV_CMD_COMPONENT_ARM_DISARM:
        v.ack(msg, cmd, _arm(v, msg) if msg.param1 >= 0.5 else _disarm(v, msg))
    elif cmd == _m.MAV_CMD_DO_SET_MODE:
        number = round(msg.param2)
        if not int(msg.param1) & _m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or number not in _MODES:
            v.ack(msg, cmd, _m.MAV_RESULT_FAILED)
            return
        set_mode(v, ap.CopterMode(number))
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_NAV_TAKEOFF:
        height = msg.z if msg.get_type() == "COMMAND_INT" else msg.param7
        if v.mode != ap.GUIDED or not v.armed or v.in_air or not 0 < height < 1000:
            v.statustext(_m.MAV_SEVERITY_WARNING, "Takeoff: not armed in GUIDED on the ground")
            v.ack(msg, cmd, _m.MAV_RESULT_FAILED)
            return
        p = v.model.position[v.index]
        v.model.hold(v.index, np.array([p[0], p[1], -float(height)]))
        v.ardu.taking_off = True
        v.event(f"takeoff to {float(height):g} m")
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_NAV_LAND:
        set_mode(v, ap.LAND)
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)
    elif cmd == _m.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        set_mode(v, ap.RTL)
        v.ack(msg, cmd, _m.MAV_RESULT_ACCEPTED)


def _arm(v: ArduHost, msg: Any) -> int:
    if v.armed:
        return int(_m.MAV_RESULT_ACCEPTED)
    if v.terminated or v.config.autopilot != "ardupilot":
        return int(_m.MAV_RESULT_FAILED)
    if v.now() < v.config.settle_time:  # ArduCopter: every failing check as "PreArm: ..."
        v.statustext(_m.MAV_SEVERITY_CRITICAL, f"{ap.PREARM_PREFIX}Need Position Estimate")
        return int(_m.MAV_RESULT_FAILED)
    if getattr(getattr(v, "faults", None), "refuse_arming", False):
        v.statustext(_m.MAV_SEVERITY_CRITICAL, f"{ap.PREARM_PREFIX}injected fault")
        return int(_m.MAV_RESULT_FAILED)
    v.arm()
    v.ardu.landed_since = None
    return int(_m.MAV_RESULT_ACCEPTED)


def _disarm(v: ArduHost, msg: Any) -> int:
    if v.armed and v.in_air and msg.param2 != 21196:
        v.statustext(_m.MAV_SEVERITY_CRITICAL, "Disarm: vehicle not landed")
        return int(_m.MAV_RESULT_FAILED)
    v.disarm("external command")
    v.in_air = False
    return int(_m.MAV_RESULT_ACCEPTED)


def heard(v: ArduHost, msg: Any, now: float) -> None:
    """A message that reached the handlers: the ground station's HEARTBEAT keeps its GCS
    failsafe off."""
    if msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == int(
            v.params.value("MAV_GCS_SYSID")):
        v.ardu.last_gcs_heartbeat = now


def follow(v: ArduHost, position: np.ndarray, velocity: np.ndarray,
           acceleration: np.ndarray) -> bool:
    """Take a position target: followed in GUIDED once airborne (True), else ignored; one
    that arrives while a takeoff has not yet left the ground ends it there."""
    i = v.index
    if v.mode != ap.GUIDED or not v.in_air:
        if v.mode == ap.GUIDED and v.ardu.taking_off:
            v.ardu.taking_off = False
            p = v.model.position[i]
            v.model.hold(i, np.array([p[0], p[1], 0.0]))
            v.event("guided: takeoff ended by a position target while still landed")
        return False
    v.model.position_sp[i] = position
    v.model.velocity_sp[i] = velocity
    v.model.acceleration_sp[i] = acceleration
    v.ardu.guided_velocity = np.nan_to_num(np.asarray(velocity, dtype=float))
    v.ardu.guided_stopped = not np.any(v.ardu.guided_velocity)
    return True


def tick(v: ArduHost, now: float) -> None:
    """GUID_TIMEOUT, the GCS failsafe, RTL's return, landing and the fence."""
    state = v.ardu
    i = v.index
    guid_timeout = v.params.value("GUID_TIMEOUT")
    if (v.mode == ap.GUIDED and not state.guided_stopped
            and now - v.last_setpoint_time > guid_timeout):
        # the target moved on with its velocity for GUID_TIMEOUT, then stops there
        target = v.model.position_sp[i] + state.guided_velocity * guid_timeout
        v.model.hold(i, np.nan_to_num(target, nan=float(v.model.position[i, 2])))
        state.guided_stopped = True
        v.event("guided: velocity target timed out", now)
    _gcs_failsafe(v, now)
    if v.mode == ap.RTL and v.armed and np.hypot(*v.model.position[i, :2]) < _RTL_REACHED_M:
        v.model.descend(i, ap.LAND_SPEED)
    _landing(v, now)
    _fence(v)


def _gcs_failsafe(v: ArduHost, now: float) -> None:
    state = v.ardu
    action = int(v.params.value("FS_GCS_ENABLE"))
    if not (v.armed and v.in_air) or action == 0 or state.gcs_failsafe:
        return
    if now - state.last_gcs_heartbeat <= v.params.value("FS_GCS_TIMEOUT") \
            or not math.isfinite(state.last_gcs_heartbeat):
        return
    state.gcs_failsafe = True
    name = ap.FS_GCS_ACTIONS.get(action, "Land")
    v.statustext(_m.MAV_SEVERITY_CRITICAL, "GCS Failsafe")
    v.event(f"failsafe: GCS lost, {name}", now)
    set_mode(v, ap.RTL if name == "Return" else ap.LAND)


def _landing(v: ArduHost, now: float) -> None:
    state = v.ardu
    if not (v.armed and v.in_air and v.mode in (ap.LAND, ap.RTL)):
        return
    i = v.index
    if v.model.truth[i, 2] >= -0.05 and abs(v.model.velocity[i, 2]) < 0.2:
        if state.landed_since is None:
            state.landed_since = now
        elif now - state.landed_since >= 1.0:  # the land detector, then the disarm
            v.in_air = False
            state.gcs_failsafe = False
            v.disarm("land complete")
    else:
        state.landed_since = None


def _fence(v: ArduHost) -> None:
    fence = v.geofence
    if v.params.value("FENCE_ENABLE") < 0.5 or not fence.active:
        fence.breached = v.fence_breached = False
        return
    if fence.inside(v.position_ned, 0.0, 0.0):
        fence.breached = v.fence_breached = False
        return
    new = not fence.breached
    fence.breached = v.fence_breached = True
    if new and v.armed and v.in_air:
        v.statustext(_m.MAV_SEVERITY_CRITICAL, "Fence Breach")
        v.event("geofence breached (FENCE_ACTION land)")
        set_mode(v, ap.LAND)
