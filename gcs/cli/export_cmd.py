"""`fleetplan export PLAN.json --format skyc -o show.skyc`: a plan in a show tool's format.

The plan is verified again first, as `fly` does: a show file is something to fly, so a plan
that did not converge or fails verification is refused. Exit status: 0 written; 1 refused
(the plan is not verified); 2 bad input (no plan, a scenario, a plan the format cannot hold,
a bad option, an output that cannot be written), each with a one-line message.
"""

from __future__ import annotations

import argparse

__all__ = ["FORMATS", "configure", "run"]

#: The formats `export` writes: name -> what the file is.
FORMATS: dict[str, str] = {
    "skyc": "Skybrush compiled show",
}

EXIT_WRITTEN = 0
EXIT_REFUSED = 1
EXIT_BAD_INPUT = 2


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan", help="Plan JSON (from `fleetplan plan`)")
    parser.add_argument("--format", choices=sorted(FORMATS), default="skyc",
                        help="skyc: a Skybrush compiled show (.skyc), which Skybrush Live "
                             "flies and Skybrush Viewer plays (default %(default)s)")
    parser.add_argument("-o", "--output", required=True, help="the file to write")
    parser.add_argument("--origin", metavar="LAT,LON[,AMSL]",
                        help="where the world origin (0, 0, 0) is on the Earth (degrees, "
                             "metres): the show's location, so a show tool places it")
    parser.add_argument("--title", help="the show's title (default: the scenario's name)")


def _fail(message: str, status: int = EXIT_BAD_INPUT) -> int:
    import sys

    print(f"error: {message}", file=sys.stderr)
    return status


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from gcs.cli.plan_file import read_plan
    from gcs.errors import ExportError
    from gcs.export.skyc import check_exportable, parse_origin, write_skyc
    from planner.verification.verify import refusal

    try:
        origin = None if args.origin is None else parse_origin(args.origin)
        plan = read_plan(args.plan, "export")
        check_exportable(plan)
    except ValueError as exc:  # ExportError and the plan loader's errors
        return _fail(str(exc))
    why = refusal(plan)
    if why is not None:
        return _fail(f"refusing to export the plan: {why}", EXIT_REFUSED)
    output = Path(args.output)
    try:
        size = write_skyc(plan, output, title=args.title, origin=origin)
    except ExportError as exc:
        return _fail(str(exc))
    except OSError as exc:
        return _fail(f"cannot write {output}: {exc.strerror or exc}")
    scenario = plan.scenario
    print(f"{output}: {FORMATS[args.format]}, {len(plan.vehicles)} drones, "
          f"{scenario.horizon:g} s, {size / 1024:.1f} KiB (show frame: the plan's world "
          f"frame, x east, y north, z up"
          + ("" if origin is None else f", origin {origin.lat:.7f}, {origin.lon:.7f}") + ")")
    return EXIT_WRITTEN
