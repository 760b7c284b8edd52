"""Entry point of the `fleetplan` command.

Each subcommand lives in its own module exposing `configure(parser)` (arguments only; it
imports only the definitions its flags' choices and defaults come from, which live in modules
without numpy: `gcs.fleet.choices`, `planner.model.choices`, `gcs.sim.realism`) and
`run(args) -> int` (the work, heavy imports inside), so `fleetplan --help` stays fast and the
subcommands stay independent of each other.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

__all__ = ["build_parser", "main"]

#: (subcommand, module, one-line help)
COMMANDS: tuple[tuple[str, str, str], ...] = (
    ("plan", "gcs.cli.plan_cmd", "plan collision-free trajectories for a scenario"),
    ("fly", "gcs.cli.fly_cmd", "fly a plan on PX4 or ArduPilot vehicles (or mock ones) and "
     "record it"),
    ("replan", "gcs.cli.replan_cmd", "change goals or drop vehicles of a running `fleetplan fly "
     "--control`"),
    ("export", "gcs.cli.export_cmd", "write a plan as a show file (Skybrush .skyc)"),
    ("report", "gcs.cli.report_cmd", "write a plan's validation report (one HTML file)"),
    ("import", "gcs.cli.import_cmd", "read a show tool's show (.skyc, Skybrush CSV) as a "
     "formation sequence"),
    ("fleet", "gcs.cli.fleet_cmd", "command vehicles between flights: hold, land, rtl, disarm, "
     "terminate"),
    ("mock", "gcs.cli.mock_cmd", "run mock vehicles, PX4 or ArduCopter (on PX4 SITL's ports)"),
    ("serve", "gcs.cli.serve_cmd", "serve the REST API and browser page (mock or real fleet)"),
    ("keys", "gcs.cli.keys_cmd", "make MAVLink 2 signing key files"),
)


def _version() -> str:
    """The installed package's version (the source tree's pyproject when not installed)."""
    from importlib import metadata

    try:
        return metadata.version("fleetplan")
    except metadata.PackageNotFoundError:  # a bare checkout on sys.path
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, one sub-parser per subcommand."""
    parser = argparse.ArgumentParser(
        prog="fleetplan",
        description="Plan, check and fly collision-free quadcopter fleet missions.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module_name, help_text in COMMANDS:
        module = importlib.import_module(module_name)
        sub_parser = sub.add_parser(name, help=help_text, description=help_text)
        module.configure(sub_parser)
        sub_parser.set_defaults(_module=module)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line and run the chosen subcommand; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args._module.run(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
