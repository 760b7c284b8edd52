"""First linearisation point for crowded fixed-goal fleets: the synchronised straight moves
(the default) against the dodged moves (`PlanningOptions(dodge=True)`, `planner.methods.dodge`),
each case
planned back to back with both so that they share the machine's load. Prints one JSON
document to stdout.

    python bench/first_guess.py                      # the cases of docs/benchmarks
    python bench/first_guess.py --cases sideways:100 grid-sphere:256:0
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.families.generators import grid_to_sphere, random_dense, sideways  # noqa: E402
from planner.options import PlanningOptions  # noqa: E402

DEFAULT_CASES = ["sideways:64", "sideways:64:1", "sideways:64:none:2.5:8", "sideways:100",
                 "grid-sphere:100:0", "grid-sphere:256:0", "dense:256:0"]


def scenario(case: str) -> dict[str, Any]:
    """FAMILY:N[:SEED[:SPACING:OFFSET]]; SEED 'none' (sideways only) keeps the lattice."""
    family, n, *rest = case.split(":")
    seed = None if not rest or rest[0] == "none" else int(rest[0])
    if family == "sideways":
        extra = {"spacing": float(rest[1]), "offset": float(rest[2])} if len(rest) > 2 else {}
        return sideways(int(n), seed=seed, **extra)
    if family == "grid-sphere":
        return grid_to_sphere(int(n), seed=0 if seed is None else seed)
    if family == "dense":
        return random_dense(int(n), seed=0 if seed is None else seed)
    raise SystemExit(f"error: cases: unknown family {family!r} in {case!r}")


def run(data: dict[str, Any], method: str) -> dict[str, Any]:
    options = PlanningOptions(dodge=method == "dodge")
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    plan = planner.plan(data, options=options, method="whole")
    total = time.perf_counter() - t0
    its = plan.iterations
    v = plan.verification
    row = {
        "scenario": data["name"], "vehicles": len(data["vehicles"]), "method": method,
        "status": plan.status, "verified": plan.ok, "total_s": round(total, 3),
        "scp_iterations": len(its) - 1,
        "iteration1_s": round(its[1].seconds, 3) if len(its) > 1 else 0.0,
        "iteration1_rows": its[1].separation_rows if len(its) > 1 else 0,
        "rows_per_iteration": [r.separation_rows for r in its[1:]],
        "largest_group": max((r.largest_group for r in its), default=0),
        "cost": plan.cost,
        "min_separation_continuous": None if v is None else v.min_separation_continuous,
        "load1_at_start": round(load, 2),
    }
    print(f"{data['name']:>28} {method:>13} {plan.status} {total:.2f} s", file=sys.stderr)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=DEFAULT_CASES,
                        help="FAMILY:N[:SEED[:SPACING:OFFSET]] with FAMILY sideways, "
                             "grid-sphere (fixed) or dense")
    args = parser.parse_args()
    began = time.perf_counter()
    rows = []
    for case in args.cases:
        data = scenario(case)
        for method in ("synchronised", "dodge"):
            rows.append(run(data, method))
    report = {"benchmark": "first-guess", "cpus": os.cpu_count(), "settings": vars(args),
              "runs": rows, "wall_time_s": round(time.perf_counter() - began, 1)}
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
