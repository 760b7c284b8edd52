"""What is specific to PX4: its custom flight modes and how its offboard mode is entered.

PX4 packs its mode into HEARTBEAT.custom_mode as ``main << 16 | sub << 24`` (the union
`px4_custom_mode` in PX4's commander) and takes the same two numbers as param2/param3 of
MAV_CMD_DO_SET_MODE with param1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED. A refused mode change is
answered TEMPORARILY_REJECTED (Commander::handle_command); OFFBOARD is only available while a
setpoint arrived within COM_OF_LOSS_T (offboardCheck.cpp), so the stream must be live first.
Arming is answered TEMPORARILY_REJECTED while the estimator settles after boot: retry.

Everything PX4-specific the GCS relies on lives here, behind the autopilot seam
(`gcs.autopilot.base.Autopilot`: `PX4`), so the streaming loop never asks "is this PX4?". The
mock autopilot (`gcs.sim`) uses the same tables to speak like PX4.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import ClassVar

from gcs.autopilot.base import Autopilot, read_rates
from gcs.wire import mavlink

__all__ = [
    "ACKED_TWICE",
    "ARM_TEMPORARILY_REJECTED_RETRY_S",
    "COM_DISARM_LAND_S",
    "COM_DISARM_PRFLT_S",
    "COM_FAIL_ACT_T_S",
    "COM_OF_LOSS_T_S",
    "DISARM_FORCE_MAGIC",
    "DUPLICATE_ACK_WINDOW_S",
    "GCS_LINK_PORT",
    "HOLD",
    "LAND",
    "OBL_ACTIONS",
    "OBL_HOLD",
    "OBL_LAND",
    "OFFBOARD",
    "OFFBOARD_GCS_BASE_PORT",
    "OFFBOARD_VEHICLE_BASE_PORT",
    "POSITION",
    "PX4",
    "RTL",
    "TAKEOFF",
    "UNREAD_STREAMS",
    "MainMode",
    "OffboardLossFailsafe",
    "Px4",
    "Px4Mode",
    "decode_custom_mode",
    "mode_name",
]

#: PX4 SITL's offboard/API link: instance i sends to UDP OFFBOARD_GCS_BASE_PORT + i, where
#: the GCS binds (MAVLink mode "onboard" in PX4's mavlink_main.cpp) ...
OFFBOARD_GCS_BASE_PORT = 14540
#: ... and listens on UDP OFFBOARD_VEHICLE_BASE_PORT + i.
OFFBOARD_VEHICLE_BASE_PORT = 14580
#: PX4's GCS link (QGroundControl): the vehicle sends to UDP 14550.
GCS_LINK_PORT = 14550
#: Offboard loss timeout (PX4 parameter COM_OF_LOSS_T, default 1 s).
COM_OF_LOSS_T_S = 1.0
#: Delay between a failsafe's trigger and its action (COM_FAIL_ACT_T, default 5 s): PX4 holds
#: in Position meanwhile (failsafe framework, v1.14 and later).
COM_FAIL_ACT_T_S = 5.0
#: COM_OBL_RC_ACT, the offboard-loss action, by value. The first three need manual control
#: (RC); without it PX4 falls back to Land.
OBL_ACTIONS = {0: "Position", 1: "Altitude", 2: "Manual", 3: "Return", 4: "Land", 5: "Hold",
               6: "Terminate", 7: "Disarm"}
#: COM_OBL_RC_ACT = Land.
OBL_LAND = 4
#: COM_OBL_RC_ACT = Hold (AUTO.LOITER: hovers where it stopped until commanded).
OBL_HOLD = 5
#: Auto-disarm when armed on the ground without taking off (COM_DISARM_PRFLT, default 10 s).
COM_DISARM_PRFLT_S = 10.0
#: Auto-disarm after landing (COM_DISARM_LAND, default 2 s).
COM_DISARM_LAND_S = 2.0
#: param2 of MAV_CMD_COMPONENT_ARM_DISARM that forces arming/disarming (not used by the GCS).
DISARM_FORCE_MAGIC = 21196.0
#: PX4's mission manager gives a transfer up after this long without progress
#: (MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT); until then another upload is refused
#: (MAV_MISSION_DENIED).
MISSION_PROTOCOL_TIMEOUT_S = 5.0
#: How long to wait between arming attempts answered TEMPORARILY_REJECTED.
ARM_TEMPORARILY_REJECTED_RETRY_S = 1.0
#: Commands PX4 (v1.16 SITL, observed) answers with two identical COMMAND_ACKs:
#: MAV_CMD_DO_SET_MODE (176) and MAV_CMD_REQUEST_MESSAGE (512).
ACKED_TWICE = frozenset({176, 512})
#: How long after the first ACK of such a command its second is expected (s): meanwhile an
#: identical ACK is taken for that echo, not for a newer command with the same id.
DUPLICATE_ACK_WINDOW_S = 0.25
#: (the mock's echo follows 5 ms later; a window of seconds would take the genuine answer of a
#: quick next command with the same id and result for an echo whose original was lost)


@dataclass(frozen=True)
class OffboardLossFailsafe:
    """What a PX4 vehicle does on its own once its setpoints stop (COM_OF_LOSS_T,
    COM_FAIL_ACT_T, COM_OBL_RC_ACT): after `loss_timeout` without a setpoint it leaves
    OFFBOARD and holds in Position for `action_delay`, then takes `action`."""

    loss_timeout: float = COM_OF_LOSS_T_S
    action_delay: float = COM_FAIL_ACT_T_S
    action: int = 0

    @property
    def hold_s(self) -> float:
        """Seconds from the last setpoint it received to its action."""
        return self.loss_timeout + self.action_delay

    @property
    def effective(self) -> str:
        """The action it takes without RC (PX4 falls back to Land for the modes that need
        it): Land, Return, Hold, Terminate or Disarm."""
        name = OBL_ACTIONS.get(self.action, "Land")
        return "Land" if name in ("Position", "Altitude", "Manual") else name

    def text(self) -> str:
        """"after 1 s without setpoints: Position hold for 5 s, then Land"."""
        return (f"after {self.loss_timeout:g} s without setpoints: Position hold for "
                f"{self.action_delay:g} s, then {self.effective}")


class MainMode(IntEnum):
    """PX4_CUSTOM_MAIN_MODE."""

    MANUAL = 1
    ALTCTL = 2
    POSCTL = 3
    AUTO = 4
    ACRO = 5
    OFFBOARD = 6
    STABILIZED = 7


#: PX4_CUSTOM_SUB_MODE_AUTO names.
_AUTO_SUB = {1: "READY", 2: "TAKEOFF", 3: "LOITER", 4: "MISSION", 5: "RTL", 6: "LAND",
             8: "FOLLOW_TARGET", 9: "PRECLAND"}


@dataclass(frozen=True)
class Px4Mode:
    """A PX4 flight mode as (main, sub)."""

    main: int
    """PX4_CUSTOM_MAIN_MODE."""
    sub: int = 0
    """PX4_CUSTOM_SUB_MODE_* (only meaningful for AUTO)."""

    @property
    def custom_mode(self) -> int:
        """HEARTBEAT.custom_mode encoding."""
        return (self.main << 16) | (self.sub << 24)

    @property
    def command_params(self) -> tuple[float, float, float]:
        """(param1, param2, param3) of MAV_CMD_DO_SET_MODE selecting this mode."""
        return (1.0, float(self.main), float(self.sub))  # 1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED

    @property
    def name(self) -> str:
        return mode_name(self.main, self.sub)


#: Modes the GCS uses.
OFFBOARD = Px4Mode(MainMode.OFFBOARD)
HOLD = Px4Mode(MainMode.AUTO, 3)  # AUTO.LOITER, "Hold" in QGroundControl
LAND = Px4Mode(MainMode.AUTO, 6)  # AUTO.LAND
POSITION = Px4Mode(MainMode.POSCTL)
RTL = Px4Mode(MainMode.AUTO, 5)  # AUTO.RTL: return to launch (fleet command)
TAKEOFF = Px4Mode(MainMode.AUTO, 2)  # AUTO.TAKEOFF: climb to MIS_TAKEOFF_ALT, then Hold


def decode_custom_mode(custom_mode: int) -> Px4Mode:
    """HEARTBEAT.custom_mode -> (main, sub)."""
    main = (custom_mode >> 16) & 0xFF
    sub = (custom_mode >> 24) & 0xFF
    return Px4Mode(main, sub if main == MainMode.AUTO else 0)


def mode_name(main: int, sub: int = 0) -> str:
    """A readable mode name such as ``OFFBOARD`` or ``AUTO.LOITER``."""
    try:
        name = MainMode(main).name
    except ValueError:
        return f"MODE({main},{sub})"
    if main == MainMode.AUTO:
        return f"AUTO.{_AUTO_SUB.get(sub, str(sub))}"
    return name


#: PX4 offboard-link streams the GCS never reads (`gcs.flight.link.link.DECODED_IDS` is what it
#: reads), turned off by `Px4.message_rates`: the fast ones (ATTITUDE 100/s, HIGHRES_IMU,
#: ATTITUDE_QUATERNION, GLOBAL_POSITION_INT 50/s, ODOMETRY 30/s on SITL) and the 0.5-10/s rest.
#: TIMESYNC's stream is the vehicle's own requests (10/s); the link reads only the answers to
#: the station's (`gcs.flight.link.quality`), which come whatever its stream's rate.
UNREAD_STREAMS = tuple(getattr(mavlink, f"MAVLINK_MSG_ID_{name}") for name in (
    "ATTITUDE", "HIGHRES_IMU", "ATTITUDE_QUATERNION", "GLOBAL_POSITION_INT", "ODOMETRY",
    "ALTITUDE", "ATTITUDE_TARGET", "POSITION_TARGET_LOCAL_NED", "POSITION_TARGET_GLOBAL_INT",
    "VFR_HUD", "SERVO_OUTPUT_RAW", "TIMESYNC", "SCALED_PRESSURE", "ESTIMATOR_STATUS",
    "SYSTEM_TIME", "VIBRATION"))


class Px4(Autopilot):
    """PX4 behind the seam: OFFBOARD after a live stream, arming retried while
    TEMPORARILY_REJECTED, the climb streamed, NAV_LAND, Hold, the offboard-loss failsafe."""

    key = "px4"
    title = "PX4"
    mav_autopilot = mavlink.MAV_AUTOPILOT_PX4
    follow_mode = OFFBOARD
    hold_mode = HOLD
    land_mode = LAND
    rtl_mode = RTL
    hold_words = "PX4 Hold"
    boarding = ("prestream", "follow", "arm", "climb")
    #: OFFBOARD is entered disarmed on the ground with the stream live; armed there, it stands
    #: at rest on setpoints on the ground and climbs when they climb (MAVROS's offboard
    #: takeoff). Armed, it disarms by itself after COM_DISARM_PRFLT without a takeoff.
    ground_boarding = ("prestream", "follow")
    liftoff = "setpoints"
    land_by_command = True
    arm_retry_results = frozenset({mavlink.MAV_RESULT_TEMPORARILY_REJECTED})
    arm_retry_s = ARM_TEMPORARILY_REJECTED_RETRY_S
    disarm_force_magic = DISARM_FORCE_MAGIC
    acked_twice = ACKED_TWICE
    duplicate_ack_window_s = DUPLICATE_ACK_WINDOW_S
    mission_protocol_timeout_s = MISSION_PROTOCOL_TIMEOUT_S
    streams_on_request = False
    #: PX4 checks an uploaded fence in every mode and acts by GF_ACTION (the operator's).
    fence_enable: ClassVar[Mapping[str, tuple[str, float]]] = {}
    failsafe_params: ClassVar[Mapping[str, str]] = {"COM_OF_LOSS_T": "f", "COM_FAIL_ACT_T": "f",
                                          "COM_OBL_RC_ACT": "i"}
    #: COM_OBL_RC_ACT to Land, COM_FAIL_ACT_T to the delay (COM_OF_LOSS_T is kept).
    failsafe_action_param = "COM_OBL_RC_ACT"
    failsafe_land = float(OBL_LAND)
    failsafe_hover = float(OBL_HOLD)
    failsafe_delay_param = "COM_FAIL_ACT_T"
    default_failsafe = OffboardLossFailsafe()
    left_alone = ("PX4's offboard-loss failsafe will land it",
                  "PX4's offboard-loss failsafe takes over")

    def decode_mode(self, custom_mode: int) -> Px4Mode:
        return decode_custom_mode(custom_mode)

    def message_rates(self, position_hz: float) -> dict[int, float]:
        """What the GCS needs from a PX4 offboard link, by message id, in Hz (0 = off):
        position at `position_hz`, status, landed state and GPS at 2 Hz, and every stream it
        never reads (`UNREAD_STREAMS`) off. HEARTBEAT is absent (PX4 refuses to change it);
        HOME_POSITION and BATTERY_STATUS (0.5/s, read) keep PX4's rate."""
        return {**read_rates(position_hz), **dict.fromkeys(UNREAD_STREAMS, 0.0)}

    def failsafe(self, values: Mapping[str, float]) -> OffboardLossFailsafe:
        return OffboardLossFailsafe(values["COM_OF_LOSS_T"], values["COM_FAIL_ACT_T"],
                                    int(values["COM_OBL_RC_ACT"]))


#: The PX4 autopilot.
PX4 = Px4()
