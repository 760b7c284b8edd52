"""`fleetplan import SHOW -o SEQUENCE.json`: a show designed in a show tool as a formation
sequence fleetplan plans (`fleetplan plan SEQUENCE.json`).

SHOW is a Skybrush compiled show (`.skyc`) or Skybrush CSV (a folder or a `.zip` of per-drone
files). Its hold points (or `--times`) become the formations, with their colours. Exit
status: 0 written; 2 bad input (a file that cannot be read, a bad row naming file, line and
column, a sequence the planner would refuse, an option out of range).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from planner.model.choices import ASSIGNMENTS

__all__ = ["configure", "run"]

EXIT_WRITTEN = 0
EXIT_BAD_INPUT = 2


def _times(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be seconds T1,T2,..., got {text!r}") from None


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("show", help="a Skybrush .skyc, or Skybrush CSV: a folder or .zip of "
                                     "per-drone files (Time [msec], x, y, z, Red, Green, Blue)")
    parser.add_argument("-o", "--output", required=True, help="the sequence JSON to write")
    parser.add_argument("--times", type=_times, metavar="T1,T2,...",
                        help="formations at these times (s) instead of the show's hold points")
    parser.add_argument("--dt", type=float, default=None,
                        help="the sequence's step (s; default 0.2)")
    parser.add_argument("--min-separation", type=float, default=None, metavar="R",
                        help="R (m; default the show's minDistance, else 1)")
    parser.add_argument("--min-hold", type=float, default=0.5, metavar="S",
                        help="shortest stretch with every drone at rest that is a hold point "
                             "(s, default %(default)s)")
    parser.add_argument("--assignment", choices=ASSIGNMENTS, default="fixed",
                        help="fixed: each drone keeps its design's place in every formation; "
                             "free: the planner assigns the places per leg (default "
                             "%(default)s)")
    parser.add_argument("--auto-durations", action="store_true",
                        help="let the planner choose each leg's duration instead of keeping "
                             "the design's timing")
    parser.add_argument("--max-velocity", type=float, default=None, metavar="V",
                        help="per-axis speed bound (m/s; default the show's, else 3)")
    parser.add_argument("--max-acceleration", type=float, default=None, metavar="A",
                        help="per-axis acceleration bound (m/s²; default the show's, else 3)")


def _fail(message: str) -> int:
    import sys

    print(f"error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _positive(value: float | None, option: str) -> str | None:
    import math

    if value is not None and not (math.isfinite(value) and value > 0):
        return f"{option} must be a positive number, got {value:g}"
    return None


def run(args: argparse.Namespace) -> int:
    import json
    import os

    from gcs.show.design import read_design
    from gcs.show.to_sequence import DEFAULT_DT, ImportOptions, to_sequence
    from gcs.show.tracks import ShowFileError

    for value, option in ((args.dt, "--dt"), (args.min_separation, "--min-separation"),
                          (args.max_velocity, "--max-velocity"),
                          (args.max_acceleration, "--max-acceleration")):
        if (problem := _positive(value, option)) is not None:
            return _fail(problem)
    if not args.min_hold >= 0:
        return _fail("--min-hold must be 0 or more seconds")
    options = ImportOptions(
        dt=args.dt or DEFAULT_DT, min_separation=args.min_separation, times=args.times,
        min_hold=args.min_hold, auto_durations=args.auto_durations,
        assignment=args.assignment, velocity_max=args.max_velocity,
        acceleration_max=args.max_acceleration)
    source = Path(args.show)
    if not source.exists():
        return _fail(f"{source}: no such file or folder")
    try:
        show = read_design(source)
        sequence = to_sequence(show.tracks, name=show.title, file=source.name, options=options,
                               validation=show.validation)
    except ShowFileError as exc:
        return _fail(str(exc))
    output = Path(args.output)
    try:
        temporary = output.with_name(f".{output.name}.part")
        temporary.write_text(json.dumps(sequence, indent=1) + "\n")
        os.replace(temporary, output)
    except OSError as exc:
        return _fail(f"cannot write {output}: {exc.strerror or exc}")
    formations = sequence["formations"]
    lit = "with colours" if "color" in formations[0] else "without colours"
    print(f"{output}: {len(sequence['vehicles'])} drones, {len(formations)} formations "
          f"{lit} from {source.name}; plan it: fleetplan plan {output} -o PLAN.json")
    return EXIT_WRITTEN
