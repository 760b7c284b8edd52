"""Free goal assignment benchmark: the certified sparse matching against the dense Hungarian
method, printing one JSON document (cases, medians, machine) to stdout.

    nice -n 10 python bench/assignment.py                     # 1,000 .. 16,000, seeds 0 1
    nice -n 10 python bench/assignment.py --sizes 1000 4000 --seeds 0 --dense-max 4000

Families: grid-sphere (vertical grid -> sphere shell around its centre, the show family),
sideways (the grid -> a sphere shell beside it), random (independent uniform starts and
goals, 100 m^3 per vehicle). Every case runs in its own process; its peak RSS (VmHWM) is
reset once the points exist, so peak_rss_mb is the solve's peak and base_rss_mb the process
before solving (Python, numpy, scipy imported, the points).
The dense method runs up to --dense-max vehicles (--dense-max-random for random) and gives
the optimum the sparse cost is compared with. The sparse graphs are matched by `lap`'s lapmod
when it is installed, else by scipy (each case's `matcher`). Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from planner.families.generators import grid_to_sphere, sphere_shell, vertical_grid  # noqa: E402
from planner.methods.assignment import matcher, solve_assignment  # noqa: E402

FAMILIES = ("grid-sphere", "sideways", "random")


def points(family: str, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals of one case (goals in a seeded random order)."""
    rng = np.random.default_rng(seed)
    if family == "grid-sphere":
        data = grid_to_sphere(n, seed=seed)
        starts = np.array([v["start"] for v in data["vehicles"]])
        return starts, np.array([v["goal"] for v in data["vehicles"]])
    if family == "sideways":
        grid = vertical_grid(n)
        shell = sphere_shell(n)
        radius = float(np.linalg.norm(shell[0]))
        centre = np.array([grid[:, 0].max() + radius + 4.0, 0.0, radius + 2.0])
        return grid, (shell + centre)[rng.permutation(n)]
    side = (100.0 * n) ** (1.0 / 3.0)
    return rng.random((n, 3)) * side, rng.random((n, 3)) * side


def _peak_rss_mb() -> float:
    """This process's peak RSS (VmHWM) in MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run_case(family: str, n: int, seed: int, method: str) -> dict[str, Any]:
    """One solve in this process: time, peak RSS and the certificate. The peak is reset after
    the points are generated (the sphere generator's own chunks would dominate it)."""
    import scipy.optimize
    import scipy.sparse.csgraph
    import scipy.spatial  # noqa: F401  (imported before the peak is reset)

    starts, goals = points(family, n, seed)
    Path("/proc/self/clear_refs").write_text("5")  # peak RSS := current RSS (Linux)
    base = _peak_rss_mb()
    begin = time.perf_counter()
    result = solve_assignment(starts, goals, dense_below=(10**9 if method == "dense" else 2))
    seconds = time.perf_counter() - begin
    return {
        "family": family, "vehicles": n, "seed": seed, "method": result.method,
        "matcher": matcher() if result.method == "sparse" else None,
        "load_average_at_start": list(os.getloadavg()),
        "time_s": round(seconds, 3),
        "peak_rss_mb": round(_peak_rss_mb(), 1),
        "base_rss_mb": round(base, 1),
        "cost": result.cost, "lower_bound": result.lower_bound, "gap": result.gap,
        "proven": result.proven, "rounds": result.rounds, "edges": result.edges,
    }


def summarise(cases: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Medians over seeds per family, size and method, with the sparse/dense cost ratio."""
    rows = []
    keys = sorted({(c["family"], c["vehicles"], c["method"]) for c in cases})
    for family, n, method in keys:
        group = [c for c in cases if (c["family"], c["vehicles"], c["method"])
                 == (family, n, method)]
        ratios = [c["cost_ratio_to_dense"] for c in group if "cost_ratio_to_dense" in c]
        rows.append({
            "family": family, "vehicles": n, "method": method, "seeds": len(group),
            "median_time_s": statistics.median(c["time_s"] for c in group),
            "median_peak_rss_mb": statistics.median(c["peak_rss_mb"] for c in group),
            "all_proven": all(c["proven"] for c in group),
            "max_gap": max(c["gap"] for c in group),
            "max_cost_ratio_to_dense": max(ratios) if ratios else None,
            "median_rounds": statistics.median(c["rounds"] for c in group),
        })
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 8000, 16000])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    parser.add_argument("--dense-max", type=int, default=4000,
                        help="largest fleet the dense reference runs on")
    parser.add_argument("--dense-max-random", type=int, default=8000,
                        help="the same for the random family (the dense method is fast there)")
    parser.add_argument("--case", nargs=4, metavar=("FAMILY", "N", "SEED", "METHOD"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        family, n, seed, method = args.case
        print(json.dumps(run_case(family, int(n), int(seed), method)))
        return
    begin = time.perf_counter()
    cases: list[dict[str, Any]] = []
    for n in args.sizes:
        for family in args.families:
            for seed in args.seeds:
                found: dict[str, dict[str, Any]] = {}
                for method in ("sparse", "dense"):
                    limit = args.dense_max_random if family == "random" else args.dense_max
                    if method == "dense" and n > limit:
                        continue
                    out = subprocess.run(
                        [sys.executable, __file__, "--case", family, str(n), str(seed), method],
                        check=True, capture_output=True, text=True).stdout
                    found[method] = json.loads(out)
                    print(f"{family} {n} seed {seed} {method}: {found[method]['time_s']} s",
                          file=sys.stderr, flush=True)
                if "dense" in found:
                    for case in found.values():
                        case["cost_ratio_to_dense"] = case["cost"] / found["dense"]["cost"]
                cases += found.values()
    print(json.dumps({
        "benchmark": "assignment",
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "platform": platform.platform()},
        "cases": cases,
        "summary": summarise(cases),
        "wall_time_s": round(time.perf_counter() - begin, 1),
    }, indent=1))


if __name__ == "__main__":
    main()
