"""The flight's vocabulary, defined once: flight phases, vehicle phases, event kinds and what
a replan is and does with a dropped vehicle.

A *phase* is where a flight (`FlightPhase`) or one of its vehicles (`VehiclePhase`) is inside
its run; an *event kind* (`EventKind`) names one line of a flight's event log. They are
StrEnums, so records, JSON and stored rows carry the plain value, and
`GET /api/status` publishes them (`vocabulary()`) beside the statuses. Events stored under a
kind's former value (`FORMER_EVENT_KINDS`) read as the kind it is now. The abort actions
(`AbortAction`) and the fleet commands (`FleetCommand`) are Literals, each with its values as a
tuple: the API's schemas, the CLI's choices and the checks below them take them from here.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Literal, get_args

__all__ = [
    "ABORT_ACTIONS",
    "AIRBORNE",
    "DROP_ACTIONS",
    "FLEET_COMMANDS",
    "FORMER_EVENT_KINDS",
    "AbortAction",
    "DropAction",
    "EventKind",
    "FleetCommand",
    "FlightPhase",
    "ReplanStatus",
    "VehiclePhase",
    "vocabulary",
]


#: What every vehicle of an aborted flight does: hold (PX4 Hold) or land. Strongest last: a
#: later one overrides an earlier one, never back (`gcs.flight.run.precedence`).
AbortAction = Literal["hold", "land"]
ABORT_ACTIONS: tuple[AbortAction, ...] = get_args(AbortAction)
#: The fleet commands between flights (`gcs.fleet.commands`), in the order the API documents
#: them.
FleetCommand = Literal["hold", "land", "rtl", "disarm", "terminate"]
FLEET_COMMANDS: tuple[FleetCommand, ...] = get_args(FleetCommand)


class FlightPhase(StrEnum):
    """Where a whole flight is: created, then connecting → preparing → gathering → flying
    (⇄ paused) → finishing → finished; or aborted / failed."""

    CREATED = "created"
    CONNECTING = "connecting"
    PREPARING = "preparing"
    GATHERING = "gathering"
    FLYING = "flying"
    PAUSED = "paused"
    FINISHING = "finishing"
    FINISHED = "finished"
    ABORTED = "aborted"
    FAILED = "failed"


class VehiclePhase(StrEnum):
    """Where one vehicle is inside its flight."""

    PENDING = "pending"
    CONNECTED = "connected"
    ARMING = "arming"
    CLIMBING = "climbing"
    AT_START = "at_start"
    FLYING = "flying"
    HOLDING = "holding"
    FAULTY = "faulty"
    LANDING = "landing"
    LANDED = "landed"
    LANDED_LINK_LOST = "landed_link_lost"
    """Landed and disarmed when last heard, out of reach since (not confirmed after)."""
    HOVERING = "hovering"
    STOPPED = "stopped"


#: Vehicle phases in which the vehicle is (or may be) in the air.
AIRBORNE: tuple[VehiclePhase, ...] = (
    VehiclePhase.CLIMBING, VehiclePhase.AT_START, VehiclePhase.FLYING, VehiclePhase.HOLDING,
    VehiclePhase.LANDING, VehiclePhase.FAULTY, VehiclePhase.HOVERING,
)


class ReplanStatus(StrEnum):
    """Where one in-flight replan is (`gcs.flight.replan.replan`): planning (until its switch tick),
    then switched (the fleet flies the new plan from that tick) or missed (no verified plan
    in time, or the flight changed meanwhile: the fleet goes on with its plan)."""

    PLANNING = "planning"
    SWITCHED = "switched"
    MISSED = "missed"


#: What a vehicle a replan drops does: land, or brake and hold where it stops.
DropAction = Literal["land", "hold"]
DROP_ACTIONS: tuple[DropAction, ...] = get_args(DropAction)


class EventKind(StrEnum):
    """The kind of one flight event (``{"t", "vehicle", "kind", "detail"}``)."""

    # the fleet
    MARGIN = "margin"
    MARGIN_WARNING = "margin_warning"
    STREAM_PRIORITY = "stream_priority"
    FLIGHT_START = "flight_start"
    HORIZON = "horizon"
    GOAL_ERRORS = "goal_errors"
    PAUSE = "pause"
    RESUME = "resume"
    PAUSE_LIMIT = "pause_limit"
    ABORT = "abort"
    """An abort accepted (`gcs.flight.run.precedence`): its reason and action, and whether it
    overrides one under way or repeats it."""
    COMMAND_REFUSED = "command_refused"
    """A command that lost to one under way (`gcs.flight.run.precedence`), and why."""
    ERROR = "error"
    SEPARATION_ALARM = "separation_alarm"
    STATION_STALL = "station_stall"
    LANDING_PLAN = "landing_plan"
    """An abort with land: the steerable vehicles fly a verified landing plan."""
    LANDING_FALLBACK = "landing_fallback"
    """PX4's own Land instead of a landing plan (the fleet's or one vehicle's), and why."""
    LINK_SILENT = "link_silent"
    """A vehicle's reports stopped for `SILENT_HOLD_S` (a lost link, maybe): the fleet holds
    (the flight clock stops) until it is heard again or declared lost."""
    FAILSAFE = "failsafe"
    """A vehicle's own link-loss failsafe as read and set before arming: what it does when
    the ground station is gone."""
    DESCENT_CLEAR = "descent_clear"
    """land_faulty: the unsteerable vehicle's straight descent was checked clear of every
    other vehicle's plan (`gcs.flight.safety.descent`): the others fly on."""
    DESCENT_CONFLICT = "descent_conflict"
    """land_faulty: that descent would come within R of others' plans (named): the others
    land by a plan that keeps clear of it (or, with `landing: px4`, hold where they are)
    instead of flying on."""
    REPLAN_STARTED = "replan_started"
    """An in-flight replan started: its switch time, vehicles, goals changed, dropped."""
    REPLAN_SWITCHED = "replan_switched"
    """The fleet flies the replanned plan from its switch tick (verified, planning time)."""
    REPLAN_MISSED = "replan_missed"
    """No replanned plan flown: why (late, not verified, the flight changed meanwhile); the
    fleet goes on with its plan (policy replan: the faulty vehicle as under land_faulty)."""
    GEOFENCE_SKIPPED = "geofence_skipped"
    """No geofence is uploaded, and why (fleet option `geofence: skip`, no origin known)."""
    GEOFENCE_NOT_FENCED = "geofence_not_fenced"
    """Obstacles that do not reach the ground, named: no PX4 fence can hold them."""
    # one vehicle
    HOME = "home"
    CONNECTED = "connected"
    MESSAGE_RATES = "message_rates"
    GEOFENCE = "geofence"
    """The vehicle's geofence was uploaded and read back the same."""
    GEOFENCE_RETRY = "geofence_retry"
    """An upload of the vehicle's geofence failed (why) and is tried again after a wait."""
    PREFLIGHT_OVERRIDE = "preflight_override"
    MODE = "mode"
    MODE_CHANGE = "mode_change"
    ARMED = "armed"
    CLIMB = "climb"
    AT_START = "at_start"
    FAULT = "fault"
    STATUSTEXT = "statustext"
    DROPPED_PACKETS = "dropped_packets"
    LINK_DEGRADED = "link_degraded"
    """The vehicle's link lost, delayed or jittered more than its bounds over the last
    seconds (`gcs.flight.link.quality`), with the figures."""
    LINK_RECOVERED = "link_recovered"
    """A degraded link under half of every bound for a while, with the figures."""
    LAND = "land"
    LAND_FAILED = "land_failed"
    LANDED = "landed"
    HOLD = "hold"
    HOLD_FAILED = "hold_failed"
    DISARM = "disarm"
    DISARM_FAILED = "disarm_failed"
    DISARM_UNCONFIRMED = "disarm_unconfirmed"
    NOT_DISARMED = "not_disarmed"
    STILL_ARMED = "still_armed"

    @classmethod
    def _missing_(cls, value: object) -> EventKind | None:
        """A kind's former value (`FORMER_EVENT_KINDS`) is that kind."""
        return FORMER_EVENT_KINDS.get(value) if isinstance(value, str) else None


#: Former values of event kinds, as events stored before they were renamed carry them.
FORMER_EVENT_KINDS: dict[str, EventKind] = {"mission_start": EventKind.FLIGHT_START}


def vocabulary() -> dict[str, list[str]]:
    """Every phase set, the replan statuses and the event kinds, as served by
    `GET /api/status` (``phases``, ``event_kinds``)."""
    return {
        "flight": [p.value for p in FlightPhase],
        "vehicle": [p.value for p in VehiclePhase],
        "airborne": [p.value for p in AIRBORNE],
        "replan": [s.value for s in ReplanStatus],
        "event_kinds": [k.value for k in EventKind],
    }
