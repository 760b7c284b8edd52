"""What is specific to ArduPilot (ArduCopter 4.7): its modes, GUIDED, its parameters and failsafes.

ArduCopter puts its mode number in HEARTBEAT.custom_mode and takes it as param2 of
MAV_CMD_DO_SET_MODE with param1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED. GUIDED follows
SET_POSITION_TARGET_LOCAL_NED (frame LOCAL_NED, about the EKF origin: the launch point within
centimetres, where home is reset at arming) and is accepted before arming; a copter in GUIDED
leaves the ground only by MAV_CMD_NAV_TAKEOFF. Arming is refused with MAV_RESULT_FAILED and
"PreArm: ..." STATUSTEXT until the checks pass (on SITL about 40 s after boot, until the EKF
uses GPS). Unlike PX4 it sends nothing but HEARTBEAT until streams are asked for, and a
position target is held for good when the stream stops (velocity and acceleration targets
are flown on for GUID_TIMEOUT, then stopped); its GCS failsafe (FS_GCS_ENABLE, off by
default) acts FS_GCS_TIMEOUT after the ground station's last HEARTBEAT.

Parameter names are 4.7's (`SYSID_THISMAV` became `MAV_SYSID`, `SYSID_MYGCS` `MAV_GCS_SYSID`).
ArduPilot sends and takes every parameter's value as a float (MAVLink's C-cast encoding), so the
GCS reads and writes them all as kind "f". The mock (`gcs.sim`) uses these tables to speak like
ArduCopter.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import ClassVar

from gcs.autopilot.base import Autopilot, SetpointLossFailsafe, read_rates
from gcs.wire import mavlink

__all__ = [
    "ARDUPILOT",
    "ARM_RETRY_S",
    "BRAKE",
    "FS_GCS_ACTIONS",
    "FS_GCS_HOLD",
    "FS_GCS_LAND",
    "FS_GCS_TIMEOUT_S",
    "GUIDED",
    "GUID_TIMEOUT_S",
    "LAND",
    "LAND_SPEED",
    "LOITER",
    "MISSION_UPLOAD_TIMEOUT_S",
    "PREARM_PREFIX",
    "RTL",
    "SITL_SERIAL0_BASE_PORT",
    "STABILIZE",
    "ArduPilot",
    "CopterMode",
    "CopterModeNumber",
]

#: ArduCopter SITL instance i serves MAVLink on TCP 5760 + 10 i (SERIAL0: always trusts
#: unsigned packets), 5762 + 10 i and 5763 + 10 i.
SITL_SERIAL0_BASE_PORT = 5760
#: GUIDED flies a velocity or acceleration target on for this long after the last one
#: (GUID_TIMEOUT, default 3 s); a position target is held for good.
GUID_TIMEOUT_S = 3.0
#: The GCS failsafe acts this long after the ground station's last HEARTBEAT
#: (FS_GCS_TIMEOUT, default 5 s), if FS_GCS_ENABLE is not 0 (its default).
FS_GCS_TIMEOUT_S = 5.0
#: FS_GCS_ENABLE by value: what the copter does when its ground station is lost.
FS_GCS_ACTIONS = {0: "Hold", 1: "Return", 2: "Return", 3: "Return", 4: "Land", 5: "Land",
                  6: "Return", 7: "Land"}
#: FS_GCS_ENABLE = Land.
FS_GCS_LAND = 5
#: FS_GCS_ENABLE = 0 (off): in GUIDED it holds its last position target for good.
FS_GCS_HOLD = 0
#: LAND mode's final descent (LAND_SPEED, default 50 cm/s).
LAND_SPEED = 0.5
#: How STATUSTEXT names a failed pre-arm check.
PREARM_PREFIX = "PreArm: "
#: Arming refused by a pre-arm check is tried again this often (s).
ARM_RETRY_S = 2.0
#: ArduPilot's mission item protocol gives an upload up after this long without an item
#: (MissionItemProtocol's upload timeout, 8 s).
MISSION_UPLOAD_TIMEOUT_S = 8.0


class CopterModeNumber(IntEnum):
    """ArduCopter's `Mode::Number`."""

    STABILIZE = 0
    ACRO = 1
    ALT_HOLD = 2
    AUTO = 3
    GUIDED = 4
    LOITER = 5
    RTL = 6
    CIRCLE = 7
    LAND = 9
    DRIFT = 11
    SPORT = 13
    FLIP = 14
    AUTOTUNE = 15
    POSHOLD = 16
    BRAKE = 17
    THROW = 18
    AVOID_ADSB = 19
    GUIDED_NOGPS = 20
    SMART_RTL = 21
    FLOWHOLD = 22
    FOLLOW = 23
    ZIGZAG = 24
    SYSTEMID = 25
    AUTOROTATE = 26
    AUTO_RTL = 27
    TURTLE = 28


@dataclass(frozen=True)
class CopterMode:
    """An ArduCopter flight mode by its number."""

    number: int

    @property
    def custom_mode(self) -> int:
        """HEARTBEAT.custom_mode encoding: the number itself."""
        return self.number

    @property
    def command_params(self) -> tuple[float, float, float]:
        """(param1, param2, param3) of MAV_CMD_DO_SET_MODE selecting this mode."""
        return (1.0, float(self.number), 0.0)  # 1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED

    @property
    def name(self) -> str:
        try:
            return CopterModeNumber(self.number).name
        except ValueError:
            return f"MODE({self.number})"


STABILIZE = CopterMode(CopterModeNumber.STABILIZE)
GUIDED = CopterMode(CopterModeNumber.GUIDED)
LOITER = CopterMode(CopterModeNumber.LOITER)
RTL = CopterMode(CopterModeNumber.RTL)
LAND = CopterMode(CopterModeNumber.LAND)
BRAKE = CopterMode(CopterModeNumber.BRAKE)


class ArduPilot(Autopilot):
    """ArduCopter behind the seam: streams asked for, an EKF origin, GUIDED before arming,
    arming retried while a pre-arm check fails, NAV_TAKEOFF, then setpoints; LAND mode,
    BRAKE to hold (LOITER sinks without an RC throttle at mid-stick), FS_GCS_* failsafe."""

    key = "ardupilot"
    title = "ArduPilot"
    mav_autopilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    follow_mode = GUIDED
    hold_mode = BRAKE
    land_mode = LAND
    rtl_mode = RTL
    hold_words = "ArduPilot BRAKE"
    boarding = ("origin", "follow", "arm", "takeoff", "climb")
    #: GUIDED is accepted disarmed. Landed, GUIDED ignores position targets
    #: (`ModeGuided::pos_control_run` and the others keep it on the ground while
    #: `is_disarmed_or_landed`), and a target arriving after MAV_CMD_NAV_TAKEOFF switches it
    #: out of its takeoff submode at once (`ModeGuided::set_destination`), which leaves it on
    #: the ground if it has not yet lifted off: it takes off by command, and gets setpoints
    #: only once it is up. Armed, it disarms by itself after DISARM_DELAY without a takeoff.
    ground_boarding = ("origin", "follow")
    liftoff = "takeoff"
    land_by_command = False
    arm_retry_results = frozenset({mavlink.MAV_RESULT_FAILED,
                                   mavlink.MAV_RESULT_TEMPORARILY_REJECTED})
    arm_retry_s = ARM_RETRY_S
    disarm_force_magic = 21196.0
    acked_twice: ClassVar[frozenset[int]] = frozenset()
    duplicate_ack_window_s = 0.0
    mission_protocol_timeout_s = MISSION_UPLOAD_TIMEOUT_S
    streams_on_request = True
    #: An uploaded fence acts only with FENCE_ENABLE (FENCE_TYPE's default includes polygons
    #: and circles; FENCE_ACTION's default is RTL or land).
    fence_enable: ClassVar[Mapping[str, tuple[str, float]]] = {"FENCE_ENABLE": ("f", 1.0)}
    failsafe_params: ClassVar[Mapping[str, str]] = {"FS_GCS_ENABLE": "f", "FS_GCS_TIMEOUT": "f",
                                          "GUID_TIMEOUT": "f"}
    #: FS_GCS_ENABLE to Land and FS_GCS_TIMEOUT to the delay (GUID_TIMEOUT is kept).
    failsafe_action_param = "FS_GCS_ENABLE"
    failsafe_land = float(FS_GCS_LAND)
    failsafe_hover = float(FS_GCS_HOLD)
    failsafe_delay_param = "FS_GCS_TIMEOUT"
    default_failsafe = SetpointLossFailsafe(GUID_TIMEOUT_S, math.inf, "Hold",
                                            "holds its last position target")

    left_alone = ("ArduPilot holds its last position target in GUIDED until its GCS failsafe "
                  "(FS_GCS_ENABLE) acts", "ArduPilot holds its last position target in GUIDED "
                  "until its GCS failsafe (FS_GCS_ENABLE) acts")

    def unsigned_port(self, connection: str) -> str | None:
        """SERIAL0 accepts unsigned packets whatever the key: SITL's TCP 5760 + 10 i, and a
        board's USB port (/dev/ttyACM*)."""
        scheme, _, rest = connection.partition(":")
        port = rest.rpartition(":")[2]
        if scheme == "tcp" and port.isdigit():
            offset = int(port) - SITL_SERIAL0_BASE_PORT
            if 0 <= offset < 2550 and offset % 10 == 0:
                return (f"TCP {port} is ArduPilot SITL's SERIAL0 (5760 + 10 i), which "
                        f"accepts unsigned packets whatever the key: connect to another of "
                        f"its ports ({int(port) + 2}, or --serial1 udpclient:HOST:PORT)")
        if "ttyACM" in connection or connection.startswith("/dev/serial/by-id/usb"):
            return ("a USB port is SERIAL0 on an ArduPilot board, which accepts unsigned "
                    "packets whatever the key: fly signed over a telemetry port (SERIAL1 "
                    "or 2)")
        return None

    def decode_mode(self, custom_mode: int) -> CopterMode:
        return CopterMode(int(custom_mode))

    def message_rates(self, position_hz: float) -> dict[int, float]:
        """What the GCS reads, by message id, in Hz: ArduCopter sends nothing else unasked
        (HEARTBEAT and STATUSTEXT always come)."""
        return {**read_rates(position_hz), mavlink.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
                mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: 0.5}

    def failsafe(self, values: Mapping[str, float]) -> SetpointLossFailsafe:
        """Its last target flown for GUID_TIMEOUT, then held until FS_GCS_TIMEOUT after the
        station's last HEARTBEAT, then FS_GCS_ENABLE's action (held for good when 0)."""
        action = FS_GCS_ACTIONS.get(int(values["FS_GCS_ENABLE"]), "Land")
        loss = values["GUID_TIMEOUT"]
        if action == "Hold":
            return SetpointLossFailsafe(loss, math.inf, "Hold", "holds its last position target")
        return SetpointLossFailsafe(loss, max(0.0, values["FS_GCS_TIMEOUT"] - loss), action,
                                    "holds its last position target")


#: The ArduPilot autopilot.
ARDUPILOT = ArduPilot()
