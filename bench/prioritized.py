"""The planning methods compared on the crowded families (JSON on stdout): prioritized
batches, the whole fleet, and auto (both raced on two cores, the first verified plan wins).

Each case is planned by `planner.plan` with method prioritized (unless --no-batches), whole
(unless --no-whole) and auto (unless --no-auto), one after the other in this process; wall
and CPU time (auto's arms run in child processes: their CPU is counted as the children's),
status, verification, cost, the method that planned, and the load average are recorded per
run.

    nice -n 10 python bench/prioritized.py --cases sideways:100:none gs:256:0 > out.json
"""

from __future__ import annotations

import argparse
import dataclasses
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
from planner.families.generators import grid_to_sphere, random_dense, sideways  # noqa: E402
from planner.families.obstacle_generators import forest  # noqa: E402
from planner.model.scenario import Scenario  # noqa: E402
from planner.options import PlanningOptions  # noqa: E402
from planner.scp.first_qp import solve_first_qp  # noqa: E402
from planner.scp.loop import thrust_cost  # noqa: E402
from planner.scp.solvers import make_solver  # noqa: E402


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


def _cpu() -> float:
    """CPU time of this process and its reaped children (auto's arms) so far (s)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def run(case: str, options: PlanningOptions, method: str, label: str) -> dict[str, Any]:
    scenario = build(case)
    load = os.getloadavg()[0]
    wall, cpu = time.perf_counter(), _cpu()
    result = plan(scenario, options=options, method=method)
    wall, cpu = time.perf_counter() - wall, _cpu() - cpu
    v = result.verification
    accelerations = np.stack([x.acceleration for x in result.vehicles])
    free = solve_first_qp(Scenario.from_dict(scenario).assigned(), make_solver(None))
    return {
        "case": case, "method": label, "planned_by": result.method,
        "attempts": [dataclasses.asdict(a) for a in result.attempts],
        "vehicles": len(scenario["vehicles"]),
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
    parser.add_argument("--no-auto", action="store_true", help="skip auto")
    args = parser.parse_args()
    if args.no_whole and args.no_batches and args.no_auto:
        parser.error("--no-whole, --no-batches and --no-auto together leave nothing to run")
    options = PlanningOptions(batch_size=args.batch)
    methods = [(method, label) for method, label, skip in (
        ("prioritized", f"prioritized-{args.batch or 'auto'}", args.no_batches),
        ("whole", "whole", args.no_whole), ("auto", "auto", args.no_auto)) if not skip]
    runs = []
    for case in args.cases:
        for method, label in methods:
            runs.append(run(case, options, method, label))
            print(json.dumps(runs[-1]), file=sys.stderr, flush=True)
    json.dump({"benchmark": "planning methods: prioritized, whole, auto",
               "cpus": os.cpu_count(), "runs": runs, "auto_ratios": _ratios(runs)},
              sys.stdout, indent=1)


def _ratios(runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per case: auto's wall time over the faster method's, and against the bound
    1.25 x faster + 0.5 s; whether auto planned whenever either method did."""
    out = []
    for case in dict.fromkeys(r["case"] for r in runs):
        mine = {r["method"].split("-")[0]: r for r in runs if r["case"] == case}
        if {"auto", "whole", "prioritized"} - set(mine):
            continue
        rivals = [mine["whole"], mine["prioritized"]]
        planned = [r for r in rivals if r["verified"]]
        faster = min(r["wall_s"] for r in planned or rivals)
        auto = mine["auto"]
        out.append({"case": case, "auto_s": auto["wall_s"], "faster_s": faster,
                    "ratio": round(auto["wall_s"] / max(faster, 1e-9), 2),
                    "within_bound": auto["wall_s"] <= 1.25 * faster + 0.5,
                    "plans_whatever_either_plans": auto["verified"] or not planned})
    return out


if __name__ == "__main__":
    main()
