"""Planner benchmark: prints one JSON document (scenarios, figures, machine info) to stdout.

    python bench/planner.py                  # paper cases, scale cases, dmpc2019, solvers
    python bench/planner.py --only paper-circle8 random64 --repeats 5
    python bench/planner.py --dmpc-trials 20 --no-solver-comparison

Timings are medians over --repeats runs of the same scenario (the machines are shared and
noisy); peak memory comes from one extra run under tracemalloc (numpy's allocations are
traced), so it does not slow the timed runs. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import sys
import time
import tracemalloc
from importlib import metadata
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import planner  # noqa: E402
from planner.generators import dmpc2019_scenario  # noqa: E402
from planner.scp import ScpOptions  # noqa: E402
from planner.verify import verify  # noqa: E402

EXAMPLES = ROOT / "planner" / "examples"
PAPER = [f"paper-{kind}{n}" for kind in ("circle", "random") for n in (2, 4, 6, 8)]
SCALE = ["circle16", "random16", "random64", "random128"]
PUBLISHED = json.loads((Path(__file__).parent / "dmpc2019-published.json").read_text())
PAPER_TIMES = {2: (2.45, 35), 4: (4.86, 67), 6: (6.75, 94), 8: (10.85, 168)}


def machine() -> dict[str, Any]:
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {}
    for package in ("numpy", "scipy", "piqp", "clarabel", "osqp"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = None
    return {
        "platform": platform.platform(),
        "cpu": cpu,
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "load_average_at_start": list(os.getloadavg()),
        "packages": versions,
    }


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def memory_peaks(run: Any) -> tuple[float, float | None]:
    """(peak of Python/numpy allocations, peak resident set size of the process) over `run`.

    tracemalloc sees numpy's buffers but not the solvers' C/C++ allocations; the RSS
    high-water mark (reset through /proc/self/clear_refs on Linux) sees everything,
    including the interpreter's baseline.
    """
    rss = None
    try:
        Path("/proc/self/clear_refs").write_text("5")
        can_reset = True
    except OSError:
        can_reset = False
    tracemalloc.start()
    run()
    traced = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    if can_reset:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                rss = int(line.split()[1]) / 1024
    return round(traced, 1), None if rss is None else round(rss, 1)


def profile(name: str, top: int = 20) -> list[dict[str, Any]]:
    """Where the time goes for one scenario: cProfile's top functions by own time."""
    import cProfile
    import pstats

    data = json.loads((EXAMPLES / f"{name}.json").read_text())
    profiler = cProfile.Profile()
    profiler.runcall(planner.plan, data)
    stats = pstats.Stats(profiler)
    rows = []
    for (file, line, function), (_, calls, own, cumulative, _) in stats.stats.items():
        rows.append({"function": f"{Path(file).name}:{line}:{function}", "calls": calls,
                     "own_s": round(own, 4), "cumulative_s": round(cumulative, 4)})
    rows.sort(key=lambda r: r["own_s"], reverse=True)
    return rows[:top]


def inflated_separation(scenario: planner.Scenario) -> float | None:
    """R' such that step rows at R' keep a pair >= R in between, for any motion within the
    velocity and acceleration bounds: the chord of a step is at most dt * w (w: the largest
    relative speed) and the quadratic bulges by at most dt^2/8 alpha."""
    lim = scenario.limits
    if lim.velocity_max is None or lim.acceleration_max is None:
        return None
    scale = scenario.separation_scale
    w = float(np.linalg.norm(2 * lim.velocity_max / scale))
    alpha = float(np.linalg.norm(2 * lim.acceleration_max / scale))
    r = scenario.min_separation + scenario.dt**2 * alpha / 8
    return float(np.hypot(r, scenario.dt * w / 2))


def row_modes(name: str, data: dict[str, Any], repeats: int) -> list[dict[str, Any]]:
    """Continuous-time safety three ways: the paper's step rows, step rows at an inflated
    R', and interval rows; every result checked against the true R over continuous time."""
    scenario = planner.Scenario.from_dict(data)
    out = []
    inflated = inflated_separation(scenario)
    variants: list[tuple[str, planner.Scenario, ScpOptions]] = [
        ("step rows (paper)", scenario, ScpOptions(continuous=False)),
        ("interval rows", scenario, ScpOptions(continuous=True)),
    ]
    if inflated is not None:
        bigger = dataclasses.replace(scenario, min_separation=inflated)
        variants.insert(1, (f"step rows, R' = {inflated:.3f}", bigger,
                            ScpOptions(continuous=False)))
    for label, variant, options in variants:
        times = []
        for _ in range(repeats):
            try:
                plan = planner.plan(variant, options=options)
            except planner.ScenarioError as exc:  # R' too large for the starts/goals
                out.append({"scenario": name, "mode": label, "error": str(exc)})
                break
            times.append(plan.timing["total_s"])
        else:
            check = verify(scenario, plan.positions(), plan.velocities(), plan.accelerations())
            out.append({
                "scenario": name, "mode": label, "status": plan.status,
                "total_s": statistics.median(times), "cost": plan.cost,
                "min_separation_steps": check.min_separation,
                "min_separation_continuous": check.min_separation_continuous,
                "R": scenario.min_separation, "separated": check.separated,
            })
            log(f"{name:>24} {label:>28} {out[-1]['total_s']:.3f} s continuous min "
                f"{check.min_separation_continuous:.4f} (R {scenario.min_separation})")
    return out


def measure(name: str, data: dict[str, Any], repeats: int, solver: str | None,
            memory: bool = True) -> dict[str, Any]:
    """Plan `repeats` times; figures of the last run, medians of the timings."""
    scenario = planner.Scenario.from_dict(data)
    totals, firsts = [], []
    plan = None
    for _ in range(repeats):
        plan = planner.plan(scenario, solver=solver)
        totals.append(plan.timing["total_s"])
        firsts.append(plan.timing["first_qp_s"])
    assert plan is not None
    peak_traced = peak_rss = None
    if memory:
        peak_traced, peak_rss = memory_peaks(lambda: planner.plan(scenario, solver=solver))
    v = plan.verification
    result = {
        "scenario": name,
        "vehicles": len(scenario.vehicles),
        "steps": scenario.steps,
        "solver": plan.solver,
        "status": plan.status,
        "verified": plan.ok,
        "total_s": statistics.median(totals),
        "total_s_runs": [round(t, 4) for t in totals],
        "first_qp_s": statistics.median(firsts),
        "scp_iterations": len(plan.iterations) - 1,
        "qp_solves": sum(r.qp_solves for r in plan.iterations),
        "separation_rows_max": max((r.separation_rows for r in plan.iterations), default=0),
        "separation_rows_last": plan.iterations[-1].separation_rows if plan.iterations else 0,
        "groups_per_iteration": [r.groups for r in plan.iterations[1:]],
        "largest_group_per_iteration": [r.largest_group for r in plan.iterations[1:]],
        "cost": plan.cost,
        "min_separation": None if v is None else v.min_separation,
        "min_separation_continuous": None if v is None else v.min_separation_continuous,
        "R": scenario.min_separation,
        "peak_memory_traced_mb": peak_traced,
        "peak_rss_mb": peak_rss,
    }
    log(f"{name:>24} {plan.status:>14} {result['total_s']:.3f} s "
        f"(first QP {result['first_qp_s']:.3f} s) iterations {result['scp_iterations']} "
        f"min sep {result['min_separation_continuous']}")
    return result


def dmpc(sizes: list[int], trials: int, repeats: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for n in sizes:
        rows = [measure(f"dmpc2019-n{n}-t{t}", dmpc2019_scenario(n, seed=2019, trial=t),
                        repeats, None, memory=False) for t in range(trials)]
        times = [r["total_s"] for r in rows]
        published = PUBLISHED["per_N"][str(n)]["cup_SCP"]
        out[str(n)] = {
            "trials": trials,
            "verified": sum(r["verified"] for r in rows),
            "time_s_median": statistics.median(times),
            "time_s_mean": statistics.fmean(times),
            "time_s_max": max(times),
            "scp_iterations_median": statistics.median(r["scp_iterations"] for r in rows),
            "min_separation_continuous_min": min(r["min_separation_continuous"] for r in rows),
            "published_cup_scp": {k: published[k] for k in ("time_s_mean", "time_s_median",
                                                             "success_rate")},
            "speedup_vs_published_median": published["time_s_median"]
            / statistics.median(times),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", help="example scenarios to run (default: all)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dmpc-sizes", type=int, nargs="*", default=[12, 20])
    parser.add_argument("--dmpc-trials", type=int, default=10)
    parser.add_argument("--no-solver-comparison", action="store_true")
    parser.add_argument("--row-modes", nargs="*", default=["paper-circle8", "random128"],
                        help="scenarios on which to compare continuous-time safety methods")
    parser.add_argument("--profile", nargs="*", default=[],
                        help="example scenarios to profile (cProfile, top functions)")
    args = parser.parse_args()

    began = time.perf_counter()
    report: dict[str, Any] = {"benchmark": "planner", "machine": machine(),
                              "settings": vars(args)}
    names = args.only if args.only is not None else PAPER + SCALE
    report["scenarios"] = [
        measure(name, json.loads((EXAMPLES / f"{name}.json").read_text()), args.repeats, None)
        for name in names
    ]
    for row in report["scenarios"]:
        n = row["vehicles"]
        if row["scenario"].startswith("paper-") and n in PAPER_TIMES:
            row["paper_total_s"] = PAPER_TIMES[n][1]
            row["speedup_vs_paper"] = PAPER_TIMES[n][1] / row["total_s"]
    if args.dmpc_sizes and args.dmpc_trials:
        report["dmpc2019"] = dmpc(args.dmpc_sizes, args.dmpc_trials, 1)
    if not args.no_solver_comparison:
        comparison = []
        for solver in ("piqp", "clarabel", "osqp"):
            for name in ("paper-circle8", "paper-random8", "random16"):
                data = json.loads((EXAMPLES / f"{name}.json").read_text())
                row = measure(name, data, args.repeats, solver, memory=False)
                comparison.append({k: row[k] for k in ("scenario", "solver", "status",
                                                       "verified", "total_s", "cost")})
        report["solvers"] = comparison
    if args.row_modes:
        report["continuous_time"] = [
            row for name in args.row_modes
            for row in row_modes(name, json.loads((EXAMPLES / f"{name}.json").read_text()),
                                 args.repeats)
        ]
    if args.profile:
        report["profiles"] = {name: profile(name) for name in args.profile}
    report["wall_time_s"] = time.perf_counter() - began
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
