"""The whole-fleet SCP core's speed floors: prints one JSON document to stdout.

    python bench/floors.py                        # every case, 5 repeats (3 for the large)
    python bench/floors.py --only paper-random8 dense2000 --repeats 3

Each case is planned with default settings (grid -> sphere 1,000 fixed in prioritized
batches, the method that meets its floor) and its plan must converge and verify. Reported
per case: the median over repeats of the planner's own time (`plan.timing["total_s"]`), of
the wall time around `planner.plan` and of the process's CPU time, each repeat's figures,
the floor, and the load average after it (the machine is shared: compare CPU time and
ratios when it is busy). The first plan of a process pays for imports and caches, so one
untimed plan of paper-circle2 runs first.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.families.generators import grid_to_sphere, random_dense  # noqa: E402
from planner.families.obstacle_generators import pillar_circle  # noqa: E402

EXAMPLES = ROOT / "planner" / "examples"
PAPER = [f"paper-{kind}{n}" for kind in ("circle", "random") for n in (2, 4, 6, 8)]
#: Case name -> (the scenario, the floor in s on a quiet 2-core machine, what the floor
#: bounds: "planner" the planner's own time, "wall" the call's wall time). Every case is
#: planned with the default settings (method auto).
CASES: dict[str, tuple[Any, float, str]] = {
    **{name: (lambda name=name: json.loads((EXAMPLES / f"{name}.json").read_text()), 0.05,
              "planner") for name in PAPER},
    "pillar-circle8": (lambda: pillar_circle(8, seed=0), 0.5, "wall"),
    "dense1000": (lambda: random_dense(1000, seed=0), 3.0, "wall"),
    "dense2000": (lambda: random_dense(2000, seed=0), 15.0, "wall"),
    "grid-sphere1000": (lambda: grid_to_sphere(1000, seed=0), 30.0, "wall"),
}
#: Cases of this many vehicles or more run `--large-repeats` times.
LARGE = 500


def run(name: str, repeats: int, large_repeats: int) -> dict[str, Any]:
    make, floor, bounds = CASES[name]
    data = make()
    if len(data["vehicles"]) >= LARGE:
        repeats = large_repeats
    planner_s, wall_s, cpu_s = [], [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        plan = planner.plan(data)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        verified = plan.verification is not None and plan.verification.verified
        if plan.status != "converged" or not verified:
            raise SystemExit(f"{name}: {plan.status}, verified {verified}: {plan.message}")
        planner_s.append(plan.timing["total_s"])
        wall_s.append(wall)
        cpu_s.append(cpu)
    median = statistics.median(planner_s if bounds == "planner" else wall_s)
    row = {
        "case": name, "vehicles": len(data["vehicles"]), "floor_s": floor,
        "floor_of": bounds, "method": plan.method,
        "median_planner_s": round(statistics.median(planner_s), 4),
        "median_wall_s": round(statistics.median(wall_s), 4),
        "median_cpu_s": round(statistics.median(cpu_s), 4), "meets_floor": median <= floor,
        "planner_s": [round(x, 4) for x in planner_s], "cpu_s": [round(x, 4) for x in cpu_s],
        "iterations": len(plan.iterations) - 1, "cost": plan.cost,
        "load_average": [round(x, 2) for x in os.getloadavg()],
    }
    print(f"{name}: planner {row['median_planner_s']} s, cpu {row['median_cpu_s']} s "
          f"(floor {floor} s of {bounds}), load {row['load_average']}", file=sys.stderr,
          flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--only", nargs="+", choices=sorted(CASES), default=list(CASES))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--large-repeats", type=int, default=3)
    args = parser.parse_args()
    planner.plan(json.loads((EXAMPLES / "paper-circle2.json").read_text()))  # warm up
    start = [round(x, 2) for x in os.getloadavg()]
    rows = [run(name, args.repeats, args.large_repeats) for name in args.only]
    print(json.dumps({"load_average_at_start": start, "cpus": os.cpu_count(),
                      "cases": rows}, indent=2))


if __name__ == "__main__":
    main()
