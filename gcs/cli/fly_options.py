"""The fleet file's flight options as `fleetplan fly` flags: one flag per `FlightOptions`
field a user often changes, its choices and the default its help states taken from the
flight options' own (`gcs.fleet.choices`, where `FlightOptions` takes them from), so the flags
cannot say other than the file they override, and building the parser loads no numpy."""

from __future__ import annotations

import argparse
from typing import Any

from gcs.fleet import choices
from gcs.wire import MAX_RATE_HZ

__all__ = ["OPTION_FLAGS", "add_flags", "chosen"]

#: (flag, its `FlightOptions` field, the field's default, which the help states, the field's
#: choices as the flag's or None, help): the flags that set a flight option. A flag without
#: choices is checked as the fleet file's (`FlightOptions.replace`), its error naming the
#: option.
_FLAGS: tuple[tuple[str, str, float | str, tuple[str, ...] | None, str], ...] = (
    ("rate", "rate_hz", choices.DEFAULT_RATE_HZ, None,
     f"setpoint rate (Hz, above {choices.MIN_RATE_HZ:g}, max {MAX_RATE_HZ:g})"),
    ("policy", "policy", choices.DEFAULT_POLICY, None,
     f"what to do when a vehicle is flagged: {', '.join(choices.POLICIES)}; replan: it lands "
     "on its own, the others are replanned around it"),
    ("replan-lead", "replan_lead_s", choices.DEFAULT_REPLAN_LEAD_S, None,
     "an in-flight replan switches this far ahead (s)"),
    ("at-end", "at_end", choices.DEFAULT_AT_END, choices.AT_END,
     "after the plan: land, or hold in PX4 Hold mode"),
    ("hold-at-goal", "hold_at_goal", choices.DEFAULT_HOLD_AT_GOAL, None, "seconds at the goals"),
    ("climb-speed", "climb_speed", choices.DEFAULT_CLIMB_SPEED, None,
     "peak speed of the climb from home to the start (m/s)"),
    ("prestream", "prestream", choices.DEFAULT_PRESTREAM, None,
     "seconds of hold setpoints before OFFBOARD is asked for"),
    ("tracking-error-max", "tracking_error_max", choices.DEFAULT_TRACKING_ERROR_MAX, None,
     "flag a vehicle this far from the plan (m)"),
    ("start-tolerance", "start_tolerance", choices.DEFAULT_START_TOLERANCE, None,
     "start the clock when all are this close to their starts (m)"),
    ("arm-timeout", "arm_timeout", choices.DEFAULT_ARM_TIMEOUT, None,
     "retry TEMPORARILY_REJECTED arming this long (s)"),
    ("margin-check", "margin_check", choices.DEFAULT_MARGIN_CHECK, choices.MARGIN_CHECK,
     "a plan whose separation margin is below 2 x the fleet's position_error: refuse, or warn "
     "and fly"),
    ("message-rates", "message_rates", choices.DEFAULT_MESSAGE_RATES, choices.MESSAGE_RATES,
     "request: ask each vehicle for the telemetry the GCS reads at the rates it needs and turn "
     "PX4's fast streams off"),
    ("stream-priority", "stream_priority", choices.DEFAULT_STREAM_PRIORITY,
     choices.STREAM_PRIORITY,
     "realtime: stream setpoints at SCHED_RR priority where the process may (root or "
     "CAP_SYS_NICE); keeps a large fleet's stream on time on a busy computer"),
)

#: The flags that set a flight option (their argparse dest) -> its `FlightOptions` field.
OPTION_FLAGS = {flag.replace("-", "_"): field for flag, field, _, _, _ in _FLAGS}


def add_flags(parser: argparse.ArgumentParser) -> None:
    """Add the flight-option flags (`OPTION_FLAGS`), each help ending in the field's default."""
    for flag, _field, default, allowed, text in _FLAGS:
        shown = f"{default:g}" if isinstance(default, float) else default
        parser.add_argument(f"--{flag}", choices=allowed,
                            type=float if isinstance(default, float) else str,
                            help=f"{text} (default {shown})")


def chosen(args: argparse.Namespace) -> dict[str, Any]:
    """The flight options given on the command line, by `FlightOptions` field (for
    `FlightOptions.replace`, which checks them as the fleet file's)."""
    return {field: getattr(args, flag) for flag, field in OPTION_FLAGS.items()
            if getattr(args, flag) is not None}
