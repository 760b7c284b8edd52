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

#: The flags that set a flight option (their argparse dest) -> its `FlightOptions` field.
OPTION_FLAGS = {"rate": "rate_hz", "policy": "policy", "at_end": "at_end",
                "hold_at_goal": "hold_at_goal", "climb_speed": "climb_speed",
                "prestream": "prestream", "tracking_error_max": "tracking_error_max",
                "start_tolerance": "start_tolerance", "arm_timeout": "arm_timeout",
                "margin_check": "margin_check", "message_rates": "message_rates",
                "stream_priority": "stream_priority", "replan_lead": "replan_lead_s"}

#: The flight options' defaults, which the flags' help states.
_DEFAULTS = FlightOptions()


def _default(field: str) -> str:
    """The help's "default V": the fleet file's default of the `FlightOptions` field."""
    value = getattr(_DEFAULTS, field)
    return f"default {value:g}" if isinstance(value, float) else f"default {value}"


def add_flags(parser: argparse.ArgumentParser) -> None:
    """Add the flight-option flags (`OPTION_FLAGS`)."""
    parser.add_argument("--rate", type=float,
                        help=f"setpoint rate (Hz, {_default('rate_hz')}, above "
                             f"{MIN_RATE_HZ:g}, max {MAX_RATE_HZ:g})")
    parser.add_argument("--policy",
                        help=f"what to do when a vehicle is flagged: {', '.join(POLICIES)} "
                             f"({_default('policy')}); replan: it lands on its own, the "
                             "others are replanned around it; checked as the fleet file's")
    parser.add_argument("--replan-lead", type=float,
                        help=f"an in-flight replan switches this far ahead (s, "
                             f"{_default('replan_lead_s')})")
    parser.add_argument("--at-end", choices=AT_END,
                        help=f"after the plan: land, or hold in PX4 Hold mode "
                             f"({_default('at_end')})")
    parser.add_argument("--hold-at-goal", type=float,
                        help=f"seconds at the goals ({_default('hold_at_goal')})")
    parser.add_argument("--climb-speed", type=float,
                        help=f"peak speed of the climb from home to the start (m/s, "
                             f"{_default('climb_speed')})")
    parser.add_argument("--prestream", type=float,
                        help=f"seconds of hold setpoints before OFFBOARD is asked for "
                             f"({_default('prestream')})")
    parser.add_argument("--tracking-error-max", type=float,
                        help=f"flag a vehicle this far from the plan (m, "
                             f"{_default('tracking_error_max')})")
    parser.add_argument("--start-tolerance", type=float,
                        help=f"start the clock when all are this close to their starts (m, "
                             f"{_default('start_tolerance')})")
    parser.add_argument("--arm-timeout", type=float,
                        help=f"retry TEMPORARILY_REJECTED arming this long (s, "
                             f"{_default('arm_timeout')})")
    parser.add_argument("--margin-check", choices=MARGIN_CHECK,
                        help=f"a plan whose separation margin is below 2 x the fleet's "
                             f"position_error: refuse, or warn and fly "
                             f"({_default('margin_check')})")
    parser.add_argument("--message-rates", choices=MESSAGE_RATES,
                        help=f"request: ask each vehicle for the telemetry the GCS reads at the "
                             f"rates it needs and turn PX4's fast streams off "
                             f"({_default('message_rates')})")
    parser.add_argument("--stream-priority", choices=STREAM_PRIORITY,
                        help=f"realtime: stream setpoints at SCHED_RR priority where the "
                             f"process may (root or CAP_SYS_NICE); keeps a large fleet's stream "
                             f"on time on a busy computer ({_default('stream_priority')})")


def chosen(args: argparse.Namespace) -> dict[str, Any]:
    """The flight options given on the command line, by `FlightOptions` field (for
    `FlightOptions.replace`, which checks them as the fleet file's)."""
    return {field: getattr(args, flag) for flag, field in OPTION_FLAGS.items()
            if getattr(args, flag) is not None}
