"""The flight options' choices and the defaults `fleetplan fly`'s flags state: plain values
(no numpy), so the CLI's parser reads them without loading the fleet file's parser
(`gcs.fleet.fleetfile`, which re-exports them and whose `FlightOptions` takes its defaults
from here)."""

from __future__ import annotations

from typing import Literal, get_args

__all__ = [
    "AT_END",
    "DEFAULT_ARM_TIMEOUT",
    "DEFAULT_AT_END",
    "DEFAULT_CLIMB_SPEED",
    "DEFAULT_HOLD_AT_GOAL",
    "DEFAULT_MARGIN_CHECK",
    "DEFAULT_MESSAGE_RATES",
    "DEFAULT_POLICY",
    "DEFAULT_PRESTREAM",
    "DEFAULT_RATE_HZ",
    "DEFAULT_REPLAN_LEAD_S",
    "DEFAULT_START_TOLERANCE",
    "DEFAULT_STREAM_PRIORITY",
    "DEFAULT_TRACKING_ERROR_MAX",
    "FAILSAFE",
    "GEOFENCE",
    "LANDING",
    "MARGIN_CHECK",
    "MESSAGE_RATES",
    "MIN_RATE_HZ",
    "OPTION_CHOICES",
    "PAUSE_EXPIRY",
    "POLICIES",
    "PREFLIGHT",
    "STREAM_PRIORITY",
    "AtEnd",
    "FailsafeChoice",
    "GeofenceChoice",
    "LandingChoice",
    "MarginCheck",
    "MessageRates",
    "PauseExpiry",
    "Policy",
    "Preflight",
    "StreamPriority",
]

#: PX4 leaves offboard mode when setpoints arrive at 2 Hz or slower (PX4 docs: "> 2Hz").
MIN_RATE_HZ = 2.0

# The choices of `FlightOptions`, each a Literal (the field's type, and the API's schema)
# and its values as a tuple (validation, messages).

#: Fleet policies applied when a vehicle is flagged (heartbeat lost, left OFFBOARD, tracking).
Policy = Literal["hold_all", "land_all", "land_faulty", "replan"]
POLICIES: tuple[Policy, ...] = get_args(Policy)
#: What the fleet does once the plan has ended and it has held at the goals.
AtEnd = Literal["land", "hold"]
AT_END: tuple[AtEnd, ...] = get_args(AtEnd)
#: What the fleet does when a pause lasts longer than `pause_limit`.
PauseExpiry = Literal["land", "hold"]
PAUSE_EXPIRY: tuple[PauseExpiry, ...] = get_args(PauseExpiry)
#: How an abort with land lands the fleet (`FlightOptions.landing`).
LandingChoice = Literal["planned", "px4"]
LANDING: tuple[LandingChoice, ...] = get_args(LandingChoice)
#: What `fly` does with a plan whose separation margin is below the fleet's need.
MarginCheck = Literal["refuse", "warn"]
MARGIN_CHECK: tuple[MarginCheck, ...] = get_args(MarginCheck)
#: The pre-flight gate: refuse an unfit vehicle, or fly anyway (recorded).
Preflight = Literal["check", "override"]
PREFLIGHT: tuple[Preflight, ...] = get_args(Preflight)
#: The geofence before arming (`gcs.geofence`): upload it to every vehicle, or skip it.
GeofenceChoice = Literal["upload", "skip"]
GEOFENCE: tuple[GeofenceChoice, ...] = get_args(GeofenceChoice)
#: Each vehicle's link-loss failsafe before arming (`gcs.flight.procedure.failsafe`): set it
#: or refuse the flight, or try to set it and fly on the vehicle's own where it cannot be.
FailsafeChoice = Literal["set", "try"]
FAILSAFE: tuple[FailsafeChoice, ...] = get_args(FailsafeChoice)
#: The telemetry rates: take what the vehicle sends, or ask for what the GCS reads.
MessageRates = Literal["leave", "request"]
MESSAGE_RATES: tuple[MessageRates, ...] = get_args(MessageRates)
#: The setpoint stream's thread: ordinary, or real-time where the process may.
StreamPriority = Literal["normal", "realtime"]
STREAM_PRIORITY: tuple[StreamPriority, ...] = get_args(StreamPriority)
#: FlightOptions field -> its allowed values.
OPTION_CHOICES: dict[str, tuple[str, ...]] = {
    "policy": POLICIES, "at_end": AT_END, "pause_expiry": PAUSE_EXPIRY,
    "margin_check": MARGIN_CHECK, "preflight": PREFLIGHT, "message_rates": MESSAGE_RATES,
    "stream_priority": STREAM_PRIORITY, "landing": LANDING, "geofence": GEOFENCE,
    "failsafe": FAILSAFE,
}

# The defaults of the `FlightOptions` fields `fleetplan fly` has flags for, named
# DEFAULT_<FIELD> (the field's docstring says what each means).

DEFAULT_RATE_HZ = 20.0
DEFAULT_POLICY: Policy = "land_all"
DEFAULT_AT_END: AtEnd = "land"
DEFAULT_TRACKING_ERROR_MAX = 1.0
DEFAULT_START_TOLERANCE = 0.3
DEFAULT_HOLD_AT_GOAL = 2.0
DEFAULT_CLIMB_SPEED = 1.0
DEFAULT_PRESTREAM = 0.5
DEFAULT_ARM_TIMEOUT = 30.0
DEFAULT_MARGIN_CHECK: MarginCheck = "refuse"
DEFAULT_MESSAGE_RATES: MessageRates = "leave"
DEFAULT_STREAM_PRIORITY: StreamPriority = "realtime"
DEFAULT_REPLAN_LEAD_S = 1.0
