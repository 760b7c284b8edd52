"""`fleetplan replan PATH --goal uav2=1,2,3 --drop uav3`: replan a running `fleetplan fly`.

Sends one replan to the flight's control socket (`fleetplan fly --control PATH`,
`gcs.cli.control`) and prints the replan object it answers (status planning; the flight's own
output then shows `replan_switched` or `replan_missed`). New goals come from ``--goal
ID=X,Y,Z`` (world frame ENU, m; repeatable) and/or ``--goals FILE.json`` ({"id": [x, y, z]});
``--drop ID`` (repeatable) takes a vehicle out of the plan to land (or, with ``--drop-action
hold``, hold). Exit status: 0 accepted, 1 refused by the flight (the error names the field),
2 a bad command line or no flight listening at PATH.
"""

from __future__ import annotations

import argparse
from typing import Any

from gcs.replan_request import DROP_ACTIONS

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("socket", metavar="PATH",
                        help="the control socket of the flight (fleetplan fly --control PATH)")
    parser.add_argument("--goal", action="append", default=[], metavar="ID=X,Y,Z",
                        help="a vehicle's new goal, world frame ENU in metres (repeatable)")
    parser.add_argument("--goals", metavar="FILE.json",
                        help='new goals from a JSON file: {"uav2": [x, y, z], ...} (--goal '
                             "entries are added to them)")
    parser.add_argument("--drop", action="append", default=[], metavar="ID",
                        help="take this vehicle out of the plan (repeatable)")
    parser.add_argument("--drop-action", choices=DROP_ACTIONS, default="land",
                        help="what a dropped vehicle does: land (default) or hold")


def goal_entry(text: str) -> tuple[str, list[float]]:
    """``ID=X,Y,Z`` as (id, [x, y, z]); ValueError saying what is wrong."""
    import math

    vehicle, sep, coords = text.partition("=")
    parts = coords.split(",")
    if not sep or not vehicle or len(parts) != 3:
        raise ValueError(f"--goal {text!r}: expected ID=X,Y,Z (e.g. uav2=1.5,2,3)")
    try:
        point = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"--goal {text!r}: X, Y and Z must be numbers") from None
    if not all(math.isfinite(v) for v in point):
        raise ValueError(f"--goal {text!r}: X, Y and Z must be finite")
    return vehicle, point


def body(args: argparse.Namespace) -> dict[str, Any]:
    """The replan request the arguments ask for; ValueError naming the argument."""
    import json
    from pathlib import Path

    goals: dict[str, Any] = {}
    if args.goals:
        try:
            goals = json.loads(Path(args.goals).read_text())
        except (OSError, ValueError) as exc:
            raise ValueError(f"--goals {args.goals}: {exc}") from None
        if not isinstance(goals, dict):
            raise ValueError(f"--goals {args.goals}: must hold a JSON object "
                             '{"id": [x, y, z], ...}')
    named: set[str] = set()
    for text in args.goal:
        vehicle, point = goal_entry(text)
        if vehicle in named:
            raise ValueError(f"--goal {vehicle}: given twice")
        named.add(vehicle)
        goals[vehicle] = point
    document: dict[str, Any] = {"command": "replan", "drop_action": args.drop_action}
    if goals:
        document["goals"] = goals
    if args.drop:
        document["drop"] = list(args.drop)
    return document


def run(args: argparse.Namespace) -> int:
    import asyncio
    import json
    import sys

    from gcs.cli.control import request
    from gcs.replan_request import MAX_ENTRIES, parse

    try:
        document = body(args)
        # The shape is checked here too, so a mistake is named before anything is sent.
        parse({k: v for k, v in document.items() if k != "command"}, MAX_ENTRIES,
              "{max} entries")
    except ValueError as exc:  # InvalidRequest too (a FieldError): "field: reason"
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        answer = asyncio.run(request(args.socket, document))
    except (OSError, ValueError, TimeoutError) as exc:
        print(f"error: no flight answers at {args.socket} (fleetplan fly --control "
              f"{args.socket}): {exc}", file=sys.stderr)
        return 2
    if not answer.get("ok"):
        error = answer.get("error") or {}
        where = f"{error['field']}: " if error.get("field") else ""
        print(f"refused ({error.get('type', 'error')}): {where}{error.get('reason', answer)}",
              file=sys.stderr)
        return 1
    print(json.dumps(answer["replan"], indent=2))
    return 0
