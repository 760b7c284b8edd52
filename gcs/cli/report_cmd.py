"""`fleetplan report PLAN.json -o report.html`: a plan's validation report, one
self-contained HTML file (`gcs.show.report`) for a plan, a planned sequence or a show.

Exit status: 0 written, every check passes; 1 written, some check fails (the report says
which); 2 bad input (no plan, a scenario, a malformed plan, an output that cannot be
written).
"""

from __future__ import annotations

import argparse

__all__ = ["configure", "run"]

EXIT_PASSED = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan", help="Plan JSON (from `fleetplan plan`)")
    parser.add_argument("-o", "--output", required=True, help="the HTML file to write")
    parser.add_argument("--title", help="the report's title (default: the scenario's name)")


def run(args: argparse.Namespace) -> int:
    import os
    import sys
    from pathlib import Path

    from gcs.cli.plan_file import read_plan
    from gcs.show.report import report_html

    try:
        plan = read_plan(args.plan, "report")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if not plan.vehicles:
        print(f"error: {args.plan}: the plan (status {plan.status}) has no trajectories",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    text, passed = report_html(plan, title=args.title)
    output = Path(args.output)
    temporary = output.with_name(f".{output.name}.part")
    try:
        temporary.write_text(text, encoding="utf-8")
        os.replace(temporary, output)
    except OSError as exc:
        temporary.unlink(missing_ok=True)
        print(f"error: cannot write {output}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(f"{output}: validation report, {len(plan.vehicles)} drones, "
          f"{plan.scenario.horizon:g} s, {len(text.encode()) / 1e6:.1f} MB: "
          + ("every check passes" if passed else "some checks FAIL (see the report)"))
    return EXIT_PASSED if passed else EXIT_FAILED
