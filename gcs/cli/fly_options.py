"""The fleet file's flight options as `fleetplan fly` flags: one flag per `FlightOptions`
field a user often changes, its choices and the default its help states taken from the fleet
file (`gcs.fleet.fleetfile`), so the flags cannot say other than the file they override."""

from __future__ import annotations

import argparse
from typing import Any

from gcs.fleet.fleetfile import (
    AT_END,
    MARGIN_CHECK,
    MAX_RATE_HZ,
    MESSAGE_RATES,
    MIN_RATE_HZ,
    POLICIES,
    STREAM_PRIORITY,
    FlightOptions,
)

__all__ = ["OPTION_FLAGS", "add_flags", "chosen"]

#: The flights' defaults, which each flag's help states.
_DEFAULTS = FlightOptions()

#: (flag, its `FlightOptions` field, the field's choices as the flag's or None, help): the
#: flags that set a flight option. A flag without choices is checked as the fleet file's
#: (`FlightOptions.replace`), its error naming the option.
_FLAGS: tuple[tuple[str, str, tuple[str, ...] | None, str], ...] = (
    ("rate", "rate_hz", None,
     f"setpoint rate (Hz, above {MIN_RATE_HZ:g}, max {MAX_RATE_HZ:g})"),
    ("policy", "policy", None,
     f"what to do when a vehicle is flagged: {', '.join(POLICIES)}; replan: it lands on its "
     "own, the others are replanned around it"),
    ("replan-lead", "replan_lead_s", None, "an in-flight replan switches this far ahead (s)"),
    ("at-end", "at_end", AT_END, "after the plan: land, or hold in PX4 Hold mode"),
    ("hold-at-goal", "hold_at_goal", None, "seconds at the goals"),
    ("climb-speed", "climb_speed", None, "peak speed of the climb from home to the start (m/s)"),
    ("prestream", "prestream", None, "seconds of hold setpoints before OFFBOARD is asked for"),
    ("tracking-error-max", "tracking_error_max", None, "flag a vehicle this far from the plan (m)"),
    ("start-tolerance", "start_tolerance", None,
     "start the clock when all are this close to their starts (m)"),
    ("arm-timeout", "arm_timeout", None, "retry TEMPORARILY_REJECTED arming this long (s)"),
    ("margin-check", "margin_check", MARGIN_CHECK,
     "a plan whose separation margin is below 2 x the fleet's position_error: refuse, or warn "
     "and fly"),
    ("message-rates", "message_rates", MESSAGE_RATES,
     "request: ask each vehicle for the telemetry the GCS reads at the rates it needs and turn "
     "PX4's fast streams off"),
    ("stream-priority", "stream_priority", STREAM_PRIORITY,
     "realtime: stream setpoints at SCHED_RR priority where the process may (root or "
     "CAP_SYS_NICE); keeps a large fleet's stream on time on a busy computer"),
)

#: The flags that set a flight option (their argparse dest) -> its `FlightOptions` field.
OPTION_FLAGS = {flag.replace("-", "_"): field for flag, field, _, _ in _FLAGS}


def add_flags(parser: argparse.ArgumentParser) -> None:
    """Add the flight-option flags (`OPTION_FLAGS`), each help ending in the field's default."""
    for flag, field, choices, text in _FLAGS:
        default = getattr(_DEFAULTS, field)
        shown = f"{default:g}" if isinstance(default, float) else default
        parser.add_argument(f"--{flag}", choices=choices,
                            type=float if isinstance(default, float) else str,
                            help=f"{text} (default {shown})")


def chosen(args: argparse.Namespace) -> dict[str, Any]:
    """The flight options given on the command line, by `FlightOptions` field (for
    `FlightOptions.replace`, which checks them as the fleet file's)."""
    return {field: getattr(args, flag) for flag, field in OPTION_FLAGS.items()
            if getattr(args, flag) is not None}
