"""PX4's timings of the mock vehicles as flags, one definition for `fleetplan mock` (`--land-speed`)
and `fleetplan fly --mock` (`--mock-land-speed`); bounds from `gcs.sim.config.TIMING_BOUNDS`."""

from __future__ import annotations

import argparse

__all__ = ["add_flags", "chosen"]

#: (flag, `MockConfig` field, help) of each timing flag.
_FLAGS = (
    ("status-rate", "status_rate", "HEARTBEAT, SYS_STATUS and EXTENDED_SYS_STATE rate (Hz, "
                                   "default 1 as PX4); faster confirms mode changes sooner"),
    ("land-speed", "land_speed", "descent speed when landing (m/s, default 0.7 as PX4's "
                                 "MPC_LAND_SPEED)"),
    ("disarm-after-land", "disarm_after_land", "disarm this long after touchdown (s, default "
                                               "2 as PX4's COM_DISARM_LAND)"),
)


def add_flags(parser: argparse.ArgumentParser, prefix: str = "") -> None:
    """Add the timing flags, each named `--{prefix}{flag}`."""
    for flag, _name, text in _FLAGS:
        parser.add_argument(f"--{prefix}{flag}", type=float, default=None,
                            help=f"{'--mock: ' if prefix else ''}{text}")


def chosen(args: argparse.Namespace, prefix: str = "") -> dict[str, float]:
    """The timings given, as `MockConfig` fields; ValueError naming the flag when one is out of
    its bounds."""
    from gcs.sim.config import timing_error

    timings: dict[str, float] = {}
    for flag, name, _text in _FLAGS:
        value = getattr(args, f"{prefix}{flag}".replace("-", "_"))
        if value is None:
            continue
        if (reason := timing_error(name, value)) is not None:
            raise ValueError(f"--{prefix}{flag} {reason}")
        timings[name] = value
    return timings
