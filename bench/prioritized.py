"""Prioritized batches against the whole-fleet SCP on the crowded families (JSON on stdout).

Each case is planned by `planner.plan` with `ScpOptions(decompose="prioritized")` (unless
--no-batches) and, unless --no-whole, with the default options (the whole fleet at once), one
after the other in this process; wall and CPU time, status, verification, cost and the load
average are recorded per run.

    nice -n 10 python bench/prioritized.py --cases sideways:100:none gs:256:0 > out.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # the package, not bench/planner.py

from planner import plan  # noqa: E402
from planner.first_qp import solve_first_qp  # noqa: E402
from planner.generators import grid_to_sphere, random_dense, sideways  # noqa: E402
from planner.obstacle_generators import forest  # noqa: E402
from planner.scenario import Scenario  # noqa: E402
from planner.scp import ScpOptions, thrust_cost  # noqa: E402
from planner.solvers import make_solver  # noqa: E402


def build(case: str) -> dict[str, Any]:
    """A scenario from a case name: sideways:N:SEED[:SPACING:OFFSET] (SEED none: as built),
    gs:N:SEED (grid -> sphere, fixed goals), random:N:SEED (random dense),
    forest:N:PILLARS:SIZE:SEED."""
    family, *args = case.split(":")
    if family == "sideways":
        seed = None if args[1] == "none" else int(args[1])
        spacing = float(args[2]) if len(args) > 2 else 2.0
        offset = float(args[3]) if len(args) > 3 else 4.0
        return sideways(int(args[0]), seed=seed, spacing=spacing, offset=offset)
    if family == "gs":
        return grid_to_sphere(int(args[0]), seed=int(args[1]))
    if family == "random":
        return random_dense(int(args[0]), seed=int(args[1]))
    if family == "forest":
        return forest(int(args[0]), int(args[1]), size=float(args[2]), seed=int(args[3]))
    raise SystemExit(f"error: unknown family in case {case!r}")


def run(case: str, options: ScpOptions, method: str) -> dict[str, Any]:
    scenario = build(case)
    load = os.getloadavg()[0]
    wall, cpu = time.perf_counter(), time.process_time()
    result = plan(scenario, options=options)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    v = result.verification
    accelerations = np.stack([x.acceleration for x in result.vehicles])
    free = solve_first_qp(Scenario.from_dict(scenario).assigned(), make_solver(None))
    return {
        "case": case, "method": method, "vehicles": len(scenario["vehicles"]),
        "status": result.status, "verified": bool(v is not None and v.verified),
        "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
        "cost": thrust_cost(accelerations),
        "separation_free_cost": thrust_cost(free.accelerations),
        "iterations": len(result.iterations), "message": result.message[:300],
        "load_before": round(load, 2), "load_after": round(os.getloadavg()[0], 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", required=True)
    parser.add_argument("--batch", type=int, default=None,
                        help="vehicles per batch (default: the planner's, by the fleet's motion)")
    parser.add_argument("--no-whole", action="store_true",
                        help="skip the whole-fleet SCP (for cases it takes minutes on)")
    parser.add_argument("--no-batches", action="store_true",
                        help="skip the prioritized batches (time the whole-fleet SCP alone)")
    args = parser.parse_args()
    if args.no_whole and args.no_batches:
        parser.error("--no-whole and --no-batches together leave nothing to run")
    runs = []
    for case in args.cases:
        if not args.no_batches:
            runs.append(run(case, ScpOptions(decompose="prioritized", batch_size=args.batch),
                            f"prioritized-{args.batch or 'auto'}"))
            print(json.dumps(runs[-1]), file=sys.stderr, flush=True)
        if not args.no_whole:
            runs.append(run(case, ScpOptions(), "whole"))
            print(json.dumps(runs[-1]), file=sys.stderr, flush=True)
    json.dump({"benchmark": "prioritized batches vs whole-fleet SCP", "cpus": os.cpu_count(),
               "runs": runs}, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
