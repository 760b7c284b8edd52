"""What `steps: "auto"` costs: the horizon search (`planner.methods.horizon_search`) against one
plan
at the horizon it chose, on a few families, in CPU seconds (`time.process_time`: the
machine is shared, so wall time says little). Prints one JSON document to stdout.

    python bench/horizon.py                          # the cases of docs/benchmarks
    python bench/horizon.py --cases circle-flat:12
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
from planner.families.generators import circle_swap, grid_to_sphere, sideways  # noqa: E402
from planner.families.obstacle_generators import window_wall  # noqa: E402

DEFAULT_CASES = ["circle:8", "window:8", "circle-flat:12", "circle-flat:24", "sideways:64",
                 "grid-sphere:100"]


def scenario(case: str) -> dict[str, Any]:
    """FAMILY:N. circle: the paper-like swap at alternating heights; circle-flat: a flat
    swap across a small circle (the boxes' bound is too short to pass each other)."""
    family, n = case.split(":")
    count = int(n)
    if family == "circle":
        return circle_swap(count)
    if family == "circle-flat":
        return circle_swap(count, height_step=0.0, rotation=0.0, radius=max(2.5, count / 4))
    if family == "window":
        return window_wall(count)
    if family == "sideways":
        return sideways(count)
    if family == "grid-sphere":
        return grid_to_sphere(count)
    raise ValueError(f"unknown family {family!r}")


def measure(case: str) -> dict[str, Any]:
    data = {**scenario(case), "steps": "auto"}
    began = time.process_time()
    searched = planner.plan(data)
    search_cpu = time.process_time() - began
    block = searched.horizon or {}
    chosen = block.get("chosen_steps")
    row: dict[str, Any] = {
        "case": case, "vehicles": len(data["vehicles"]), "dt": data["dt"],
        "status": searched.status, "chosen_steps": chosen,
        "lower_bound_steps": block.get("lower_bound_steps"),
        "plans": len(block.get("tried", [])), "tried": block.get("tried", []),
        "search_cpu_s": search_cpu,
    }
    if chosen is not None:
        began = time.process_time()
        single = planner.plan({**data, "steps": chosen})
        row["single_cpu_s"] = time.process_time() - began
        row["single_status"] = single.status
        row["ratio"] = search_cpu / row["single_cpu_s"] if row["single_cpu_s"] > 0 else None
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=DEFAULT_CASES, metavar="FAMILY:N")
    args = parser.parse_args()
    planner.plan(scenario("circle:2"))  # imports and solver set-up, outside the figures
    rows = [measure(case) for case in args.cases]
    print(json.dumps({"cases": rows, "cpus": os.cpu_count(),
                      "load_average": os.getloadavg()}, indent=1))


if __name__ == "__main__":
    main()
