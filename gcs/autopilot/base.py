"""The autopilot seam: what differs between the autopilots the GCS flies, as one interface.

An `Autopilot` holds the facts the procedure, the fleet commands and the flight monitors need
and that are not the same on PX4 and ArduPilot: mode encodings and which mode follows
setpoints, the boarding procedure's steps in their order, how arming refusals read and are
retried, land/hold/RTL, the parameters the GCS reads and sets (link-loss failsafe, fence),
which streams must be asked for, and what the vehicle does when setpoints stop. The link,
the streaming loop, the monitors, landing and replanning only ever ask an `Autopilot`, never
"is this PX4?". The implementations are `gcs.autopilot.px4` and `gcs.autopilot.ardupilot`;
`gcs.autopilot` chooses one from HEARTBEAT.autopilot or the fleet file.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar, Protocol

from gcs.wire import mavlink

__all__ = ["BOARDING_STEPS", "LIFTOFF_WAYS", "Autopilot", "FlightMode", "LinkLossFailsafe",
           "SetpointLossFailsafe", "read_rates"]

#: Every step a boarding procedure may name (`Autopilot.boarding`), run in the autopilot's
#: order by `gcs.flight.run.boarding.prepare_vehicle`:
#: - ``prestream``: stream setpoints holding the vehicle where it is before the mode switch
#:   (a mode that follows setpoints is refused without them);
#: - ``origin``: the vehicle has an EKF origin (GPS_GLOBAL_ORIGIN), set by the GCS where none;
#: - ``follow``: switch to `Autopilot.follow_mode`;
#: - ``arm``: arm, retried while refused with `Autopilot.arm_retry_results`;
#: - ``takeoff``: MAV_CMD_NAV_TAKEOFF to the start's height, and wait until it is there;
#: - ``climb``: stream the transfer from where it is to its start.
BOARDING_STEPS = ("prestream", "origin", "follow", "arm", "takeoff", "climb")

#: Every way a vehicle standing on the ground may leave it at its takeoff time in a show's
#: plan (`Autopilot.liftoff`), flown by `gcs.flight.run.ground`:
#: - ``setpoints``: armed in the mode that follows setpoints with the plan's setpoints
#:   streaming (at rest on the ground until then), it climbs when they climb;
#: - ``takeoff``: no setpoint may reach it between the takeoff command and leaving the ground
#:   (it would end the takeoff with the vehicle still landed): MAV_CMD_NAV_TAKEOFF to the
#:   plan's height a moment ahead, then the plan's setpoints.
LIFTOFF_WAYS = ("setpoints", "takeoff")


def read_rates(position_hz: float) -> dict[int, float]:
    """The telemetry the GCS reads from every autopilot, by message id, in Hz: position at
    `position_hz`, status, landed state and GPS at 2 Hz."""
    return {mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: position_hz,
            mavlink.MAVLINK_MSG_ID_SYS_STATUS: 2.0,
            mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 2.0,
            mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 2.0}


class FlightMode(Protocol):
    """A flight mode as the GCS sees it: its name, HEARTBEAT encoding and command."""

    @property
    def name(self) -> str: ...

    @property
    def custom_mode(self) -> int: ...

    @property
    def command_params(self) -> tuple[float, float, float]: ...


class LinkLossFailsafe(Protocol):
    """What a vehicle does on its own once setpoints stop: it flies on its last one for
    `loss_timeout` s, holds for `action_delay` s, then takes `effective` (Land, Return, Hold,
    Terminate or Disarm)."""

    @property
    def loss_timeout(self) -> float: ...

    @property
    def action_delay(self) -> float: ...

    @property
    def effective(self) -> str: ...

    @property
    def hold_s(self) -> float: ...

    def text(self) -> str: ...


@dataclass(frozen=True)
class SetpointLossFailsafe:
    """A `LinkLossFailsafe` given by its parts (`how` names the hold in the text)."""

    loss_timeout: float
    action_delay: float
    effective: str
    how: str = "hold"

    @property
    def hold_s(self) -> float:
        return self.loss_timeout + self.action_delay

    def text(self) -> str:
        """"after 3 s on its last setpoint: hold for 2 s, then Land"."""
        if self.effective == "Hold" or not math.isfinite(self.action_delay):
            return f"after {self.loss_timeout:g} s on its last setpoint: {self.how}, for good"
        return (f"after {self.loss_timeout:g} s on its last setpoint: {self.how} for "
                f"{self.action_delay:g} s, then {self.effective}")


class Autopilot(ABC):
    """One autopilot's facts (class attributes) and the few rules given as functions."""

    #: The fleet file's name for it (``autopilot: px4 | ardupilot``).
    key: ClassVar[str]
    #: How it is named to people.
    title: ClassVar[str]
    #: HEARTBEAT.autopilot (MAV_AUTOPILOT).
    mav_autopilot: ClassVar[int]
    #: The mode in which it follows SET_POSITION_TARGET_LOCAL_NED.
    follow_mode: ClassVar[FlightMode]
    #: Hold where it is (no setpoints needed), land, return to launch.
    hold_mode: ClassVar[FlightMode]
    land_mode: ClassVar[FlightMode]
    rtl_mode: ClassVar[FlightMode]
    #: `hold_mode` in words, for events ("PX4 Hold").
    hold_words: ClassVar[str]
    #: The boarding procedure's steps in order (names from `BOARDING_STEPS`).
    boarding: ClassVar[tuple[str, ...]]
    #: The boarding steps of a vehicle that takes off by the plan itself (a show standing on
    #: the ground): up to the mode that follows setpoints, disarmed; it is armed shortly
    #: before its takeoff time (`gcs.flight.run.ground`).
    ground_boarding: ClassVar[tuple[str, ...]]
    #: How it leaves the ground at its takeoff time (a name from `LIFTOFF_WAYS`).
    liftoff: ClassVar[str]
    #: MAV_CMD_NAV_LAND is tried before switching to `land_mode`.
    land_by_command: ClassVar[bool]
    #: MAV_RESULTs that refuse arming only for now (pre-arm checks not passed yet): retried
    #: every `arm_retry_s` until the arming timeout.
    arm_retry_results: ClassVar[frozenset[int]]
    arm_retry_s: ClassVar[float]
    #: param2 of MAV_CMD_COMPONENT_ARM_DISARM that forces disarming in the air.
    disarm_force_magic: ClassVar[float]
    #: Commands it answers with two identical COMMAND_ACKs, and how soon the second follows.
    acked_twice: ClassVar[frozenset[int]]
    duplicate_ack_window_s: ClassVar[float]
    #: How long its mission manager takes to give a stalled transfer up (s).
    mission_protocol_timeout_s: ClassVar[float]
    #: It sends nothing but HEARTBEAT until streams are asked for.
    streams_on_request: ClassVar[bool]
    #: Parameters to set after a fence upload so that the fence acts: name -> (kind, value).
    fence_enable: ClassVar[Mapping[str, tuple[str, float]]]
    #: Its link-loss failsafe's parameters (name -> kind "f"/"i").
    failsafe_params: ClassVar[Mapping[str, str]]
    #: What becomes of it when its setpoints stop after a land (first) or hold (second)
    #: command failed, as the end of the failure's event.
    left_alone: ClassVar[tuple[str, str]]
    #: What it does without setpoints before its parameters are read.
    default_failsafe: ClassVar[LinkLossFailsafe]

    def unsigned_port(self, connection: str) -> str | None:
        """Why a signed link on `connection` (a pymavlink URL) would still let unsigned
        packets in, where the URL shows it; None when it does not."""
        return None

    @abstractmethod
    def decode_mode(self, custom_mode: int) -> FlightMode:
        """HEARTBEAT.custom_mode -> its mode."""

    @abstractmethod
    def message_rates(self, position_hz: float) -> dict[int, float]:
        """The telemetry rates the GCS asks for (MAV_CMD_SET_MESSAGE_INTERVAL), by message
        id, in Hz (0 = off), with LOCAL_POSITION_NED at `position_hz`."""

    #: The failsafe parameter that says what it does (set to `failsafe_land`, or to
    #: `failsafe_hover` for a vehicle that must stay where it stopped), and the one that says
    #: when (set to the altitude layer's delay).
    failsafe_action_param: ClassVar[str]
    failsafe_land: ClassVar[float]
    failsafe_hover: ClassVar[float]
    failsafe_delay_param: ClassVar[str]

    def failsafe_settings(self, values: Mapping[str, float], delay: float, *,
                          hover: bool = False) -> dict[str, float]:
        """The failsafe parameters to set (name -> value, in the order to set them) so that a
        vehicle whose parameters read `values` lands `delay` s after its station is lost, or
        with `hover` stays hovering where it stopped (its column meets another's: landing it
        straight down would bring them closer than R)."""
        out: dict[str, float] = {}
        action = self.failsafe_hover if hover else self.failsafe_land
        if values[self.failsafe_action_param] != action:
            out[self.failsafe_action_param] = action
        if not math.isclose(values[self.failsafe_delay_param], delay, abs_tol=1e-3):
            out[self.failsafe_delay_param] = delay
        return out

    @abstractmethod
    def failsafe(self, values: Mapping[str, float]) -> LinkLossFailsafe:
        """What a vehicle with these failsafe parameter values does without its station."""

    def __repr__(self) -> str:
        return f"<autopilot {self.key}>"
