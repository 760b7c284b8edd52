"""Planner benchmark: prints one JSON document (scenarios, figures, machine info) to stdout.

    python bench/planner.py                  # paper cases, scale cases, dmpc2019, solvers
    python bench/planner.py --only paper-circle8 random64 --repeats 5
    python bench/planner.py --dmpc-trials 20 --no-solver-comparison
    python bench/planner.py --only --dmpc-sizes --no-solver-comparison --row-modes \
        --grid-sphere 25 64 100 256 --assignment fixed free --random-dense 256 --seeds 0 1

    python bench/planner.py --only --dmpc-sizes --no-solver-comparison --row-modes \
        --obstacles pillar-circle8 window8 shelving16 forest50 --seeds 0 1 2 --no-memory

The drone-show families run only when asked: --grid-sphere N... (vertical grid ->
sphere shell, fixed and/or free assignment), --sideways N... (the grid onto a shell beside
it, lattice order, over --sideways-layouts and --sideways-seeds), --random-dense N...
(random128's density, moves <= 40 m), --sequence N (a grid -> sphere -> grid formation
sequence; with --formations F a long show of F formations, `show_formations`), each over
--seeds. The long show's legs through Dask workers: bench/dask_engine.py --formations.
--obstacles NAME... runs the obstacle families (a pillar in the paper's circle, a window in
a wall, shelving, forests), each with its floor. --group-qp primal solves their group QPs as
the primal staged QP (for comparison with the dual); --method whole or prioritized plans
every family that way (--decompose prioritized: the same; the default is the planner's,
auto); --profile also takes
dense<N> and grid-sphere<N>.

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
import tempfile
import time
import tracemalloc
from importlib import metadata
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import planner  # noqa: E402
from planner.families.generators import (  # noqa: E402
    SHOW_SHAPES,
    SHOW_STEPS,
    dmpc2019_scenario,
    grid_to_sphere,
    random_dense,
    show_formations,
    show_sequence,
    sideways,
)
from planner.families.obstacle_generators import (  # noqa: E402
    forest,
    pillar_circle,
    shelving,
    window_wall,
)
from planner.methods.sequence import plan_sequence  # noqa: E402
from planner.model.scenario import METHODS  # noqa: E402
from planner.options import PlanningOptions  # noqa: E402
from planner.scp.loop import ScpOptions  # noqa: E402
from planner.verification.verify import verify  # noqa: E402

EXAMPLES = ROOT / "planner" / "examples"
PAPER = [f"paper-{kind}{n}" for kind in ("circle", "random") for n in (2, 4, 6, 8)]
SCALE = ["circle16", "random16", "random64", "random128"]
PUBLISHED = json.loads((Path(__file__).parent / "dmpc2019-published.json").read_text())
#: The record-scale sizes (--record): grid -> sphere with free assignment.
RECORD_SIZES = [4000, 8000, 16000]
PAPER_TIMES = {2: (2.45, 35), 4: (4.86, 67), 6: (6.75, 94), 8: (10.85, 168)}
#: The obstacle families by name: the generator of a seed's instance and the
#: floor (s, median on a quiet machine).
OBSTACLE_FAMILIES: dict[str, tuple[Any, float]] = {
    "pillar-circle8": (lambda seed: pillar_circle(8, seed=seed), 0.5),
    "window8": (lambda seed: window_wall(8, seed=seed), 2.0),
    "shelving16": (lambda seed: shelving(16, seed=seed), 2.0),
    "forest50": (lambda seed: forest(50, 40, seed=seed), 5.0),
    "forest200": (lambda seed: forest(200, 150, size=60.0, seed=seed), 30.0),
}


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


def reset_peak_rss() -> bool:
    """Reset the process's RSS high-water mark (Linux); False where that is not possible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def peak_rss_mb() -> float | None:
    """The process's RSS high-water mark (MB) since the last reset, None off Linux."""
    try:
        status = Path("/proc/self/status").read_text()
    except OSError:
        return None
    for line in status.splitlines():
        if line.startswith("VmHWM:"):
            return round(int(line.split()[1]) / 1024, 1)
    return None


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


def scenario_by_name(name: str) -> dict[str, Any]:
    """An example scenario, or a generated one: dense<N> (random_dense(N, seed=0)),
    grid-sphere<N> (grid_to_sphere(N, seed=0), fixed assignment)."""
    if name.startswith("dense") and name[5:].isdigit():
        return random_dense(int(name[5:]), seed=0)
    if name.startswith("grid-sphere") and name[11:].isdigit():
        return grid_to_sphere(int(name[11:]), seed=0)
    return json.loads((EXAMPLES / f"{name}.json").read_text())


def profile(name: str, options: PlanningOptions, top: int = 20, method: str | None = None
            ) -> list[dict[str, Any]]:
    """Where the time goes for one scenario: cProfile's top functions by own time."""
    import cProfile
    import pstats

    data = scenario_by_name(name)
    profiler = cProfile.Profile()
    profiler.runcall(planner.plan, data, options=options, method=method)
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
                plan = planner.plan(variant, options=options, method="whole")
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
            memory: bool = True, options: PlanningOptions | None = None, export: bool = False,
            method: str | None = None) -> dict[str, Any]:
    """Plan `repeats` times; figures of the last run, medians of the timings. total_s is
    the wall time of `planner.plan(dict)`: validation (and goal assignment, parse_s of it),
    planning and verification, cpu_s the process's CPU time over it (on a shared machine the
    closer figure to a quiet run's wall time); peak_rss_timed_mb the process's high-water
    mark over each timed run. export: also time writing the plan JSON (streamed) to a
    temporary file."""
    scenario = planner.Scenario.from_dict(data)
    totals, firsts, parses, rss_runs, cpus = [], [], [], [], []
    plan = None
    for _ in range(repeats):
        reset_peak_rss()
        t0, c0 = time.perf_counter(), time.process_time()
        parsed = planner.Scenario.from_dict(data)  # what plan(dict) does first
        parses.append(time.perf_counter() - t0)
        plan = planner.plan(parsed, solver=solver, options=options, method=method)
        totals.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        firsts.append(plan.timing["first_qp_s"])
        rss_runs.append(peak_rss_mb())
    assert plan is not None
    exported = None
    if export:
        t0 = time.perf_counter()
        with tempfile.TemporaryFile("w") as stream:
            plan.write_json(stream)
            size = stream.tell()
        exported = {"export_s": round(time.perf_counter() - t0, 3),
                    "export_mb": round(size / 2**20, 1), "peak_rss_with_export_mb": peak_rss_mb()}
    peak_traced = peak_rss = None
    if memory:
        peak_traced, peak_rss = memory_peaks(
            lambda: planner.plan(scenario, solver=solver, options=options, method=method))
    v = plan.verification
    result = {
        "scenario": name,
        "vehicles": len(scenario.vehicles),
        "steps": scenario.steps,
        "solver": plan.solver,
        "group_qp": "dual" if (options or PlanningOptions()).scp.dual else "primal",
        "method": scenario.method if method is None else method,
        "planned_by": plan.method,
        "attempts": [dataclasses.asdict(a) for a in plan.attempts],
        "status": plan.status,
        "message": plan.message[:300],
        "verified": plan.ok,
        "total_s": statistics.median(totals),
        "total_s_runs": [round(t, 4) for t in totals],
        "parse_s": statistics.median(parses),
        "cpu_s": statistics.median(cpus),
        "peak_rss_timed_mb": max(rss_runs) if None not in rss_runs else None,
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
        **(exported or {}),
    }
    if scenario.obstacles:
        result.update(obstacles=len(scenario.obstacles), clearance=scenario.clearance,
                      obstacle_distance_min=None if v is None else v.obstacle_distance_min,
                      closest_obstacle=None if v is None else v.closest_obstacle)
    log(f"{name:>24} {plan.status:>14} {result['total_s']:.3f} s "
        f"(first QP {result['first_qp_s']:.3f} s) iterations {result['scp_iterations']} "
        f"min sep {result['min_separation_continuous']} cpu {result['cpu_s']:.1f} s "
        f"parse {result['parse_s']:.1f} s peak RSS {result['peak_rss_timed_mb']} MB "
        f"load {[round(x, 1) for x in os.getloadavg()]}")
    return result


def sequence_case(n: int, repeats: int, formations: int = 0, seed: int = 0) -> dict[str, Any]:
    """A grid -> sphere -> grid sequence, or a long show of `formations` formations (free
    assignment): legs planned one after the other here (the service maps them over
    workers), stitched and verified as a whole."""
    if formations:
        shapes = [SHOW_SHAPES[f % 5] for f in range(formations)]
        data = show_formations(n, shapes, seed=seed)
    else:
        data = show_sequence(n)
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = plan_sequence(data)
        times.append(time.perf_counter() - t0)
    assert result is not None
    row = {
        "sequence": data["name"], "vehicles": n, "legs": len(result.legs),
        "status": result.status, "duration_s": result.duration,
        "total_s": statistics.median(times), "total_s_runs": [round(t, 3) for t in times],
        "leg_s": [round(leg.timing["total_s"], 3) for leg in result.legs],
        "min_separation_continuous": result.verification.min_separation_continuous,
        "dynamics_error": result.dynamics_error,
    }
    log(f"{data['name']:>24} {result.status:>14} {row['total_s']:.3f} s legs {row['leg_s']}")
    return row


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (family, assignment, vehicles): medians over seeds, and how many verified."""
    groups: dict[tuple[str, str, int], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["family"], row["assignment"], row["vehicles"]), []).append(row)
    out = []
    for (family, assignment, n), group in sorted(groups.items()):
        rss = [r["peak_rss_mb"] for r in group if r["peak_rss_mb"] is not None]
        out.append({
            "family": family, "assignment": assignment, "vehicles": n, "seeds": len(group),
            "group_qp": group[0]["group_qp"], "method": group[0]["method"],
            "verified": sum(r["verified"] for r in group),
            "total_s_median": statistics.median(r["total_s"] for r in group),
            "total_s_max": max(r["total_s"] for r in group),
            "scp_iterations_median": statistics.median(r["scp_iterations"] for r in group),
            "separation_rows_max": max(r["separation_rows_max"] for r in group),
            "largest_group_max": max(max(r["largest_group_per_iteration"], default=0)
                                     for r in group),
            "peak_rss_mb_max": max(rss) if rss else None,
            "min_separation_continuous_min": min(r["min_separation_continuous"] or np.inf
                                                 for r in group),
        })
    return out


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
                        help="scenarios to profile (cProfile, top functions): examples, "
                             "dense<N> or grid-sphere<N> (seed 0, fixed)")
    parser.add_argument("--grid-sphere", type=int, nargs="*", default=[],
                        help="grid -> sphere show transitions of these sizes")
    parser.add_argument("--assignment", nargs="*", default=["fixed", "free"],
                        choices=["fixed", "free"], help="assignments for --grid-sphere")
    parser.add_argument("--random-dense", type=int, nargs="*", default=[],
                        help="random transitions at random128's density of these sizes")
    parser.add_argument("--sideways", type=int, nargs="*", default=[],
                        help="grid -> a sphere shell beside it, goals in lattice order "
                             "(fixed), of these sizes")
    parser.add_argument("--sideways-layouts", nargs="*", default=["2:4"],
                        help="SPACING:OFFSET pairs (m) for --sideways")
    parser.add_argument("--sideways-seeds", nargs="*", default=["none"],
                        help="shell rotations for --sideways: 'none' (the lattice as built, "
                             "upside down against the grid) or integer seeds")
    parser.add_argument("--sequence", type=int, nargs="*", default=[],
                        help="grid -> sphere -> grid formation sequences of these sizes")
    parser.add_argument("--formations", type=int, default=0,
                        help="--sequence as long shows of this many formations (over --seeds)")
    parser.add_argument("--obstacles", nargs="*", default=[],
                        choices=list(OBSTACLE_FAMILIES),
                        help="obstacle families to run over --seeds")
    parser.add_argument("--seeds", type=int, nargs="*", default=[0])
    parser.add_argument("--group-qp", choices=["dual", "primal"], default="dual",
                        help="how the families' and profiles' group QPs are solved "
                             "(ScpOptions.dual)")
    parser.add_argument("--sized-horizon", action="store_true",
                        help="free --grid-sphere runs get the horizon their assigned moves "
                        "need (grid_to_sphere(steps=None)) instead of 30 s")
    parser.add_argument("--record", action="store_true",
                        help="the record sizes: --grid-sphere 4000 8000 16000 --assignment "
                        "free --sized-horizon")
    parser.add_argument("--export", action="store_true",
                        help="also time writing each family plan's JSON (streamed)")
    parser.add_argument("--no-memory", action="store_true",
                        help="skip the extra run that measures peak memory")
    parser.add_argument("--method", choices=METHODS, default=None,
                        help="how every case is planned (default: the scenario's, auto)")
    parser.add_argument("--decompose", choices=("none", "prioritized"), default=None,
                        help="the same as --method: none is whole")
    args = parser.parse_args()

    began = time.perf_counter()
    options = PlanningOptions(scp=ScpOptions(dual=args.group_qp == "dual"))
    method = args.method or {"none": "whole", "prioritized": "prioritized", None: None}[
        args.decompose]
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
        report["profiles"] = {name: profile(name, options, method=method)
                              for name in args.profile}
    families = []
    if args.record:
        args.grid_sphere, args.assignment, args.sized_horizon = RECORD_SIZES, ["free"], True
    for n in args.grid_sphere:
        for assignment in args.assignment:
            for seed in args.seeds:
                sized = args.sized_horizon and assignment == "free"
                t0 = time.perf_counter()
                data = {**grid_to_sphere(n, seed=seed, steps=None if sized else SHOW_STEPS),
                        "assignment": assignment}
                made = time.perf_counter() - t0
                row = measure(f"{data['name']}-{assignment}", data, args.repeats, None,
                              memory=not args.no_memory, options=options, export=args.export,
                              method=method)
                families.append({"family": "grid-sphere", "assignment": assignment,
                                 "seed": seed, "sized_horizon": sized,
                                 "horizon_s": data["steps"] * data["dt"],
                                 "generator_s": round(made, 2), **row})
    for n in args.sideways:
        for layout in args.sideways_layouts:
            spacing, offset = (float(x) for x in layout.split(":"))
            for text in args.sideways_seeds:
                seed = None if text == "none" else int(text)
                data = sideways(n, seed=seed, spacing=spacing, offset=offset)
                row = measure(data["name"], data, args.repeats, None,
                              memory=not args.no_memory, options=options,
                              method=method)
                families.append({"family": f"sideways s{spacing:g} o{offset:g}",
                                 "assignment": "fixed", "seed": seed,
                                 "spacing": spacing, "offset": offset, **row})
    for n in args.random_dense:
        for seed in args.seeds:
            row = measure(f"dense{n}-seed{seed}", random_dense(n, seed=seed), args.repeats,
                          None, memory=not args.no_memory, options=options,
                              method=method)
            families.append({"family": "random-dense", "assignment": "fixed", "seed": seed,
                             **row})
    for family in args.obstacles:
        make, floor = OBSTACLE_FAMILIES[family]
        for seed in args.seeds:
            row = measure(f"{family}-seed{seed}", make(seed), args.repeats, None,
                          memory=not args.no_memory, options=options,
                              method=method)
            families.append({"family": family, "assignment": "fixed", "seed": seed,
                             "floor_s": floor, "within_floor": row["total_s"] <= floor,
                             **row})
    if families:
        report["families"] = families
        report["families_summary"] = summarise(families)
    if args.sequence:
        seeds = args.seeds if args.formations else [0]
        report["sequences"] = [sequence_case(n, args.repeats, args.formations, seed)
                               for n in args.sequence for seed in seeds]
    report["wall_time_s"] = time.perf_counter() - began
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
