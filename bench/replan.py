"""Replan benchmark (planner level, no flight): how long `planner.methods.replan.plan_replan` takes
to
replan a flying fleet from its exact state, for several families and sizes; prints one JSON
document to stdout.

    python bench/replan.py                                   # the default cases below
    python bench/replan.py --families circle --sizes 16 --seeds 0 --at 0.5

For each family (``circle``: `circle_swap`, everyone through the centre; ``random``:
`random_transitions` in a box sized for the fleet; ``grid-sphere``: `grid_to_sphere`, a show
transition crossing the middle), size and seed, the source plan is planned once; then at
each instant (a share of its horizon: 0.5 is the middle of the crossing) every vehicle's
exact state is taken from it (position, velocity, acceleration) and two replans are timed:

- ``goals+drop``: about a quarter of the goals change to new valid ones (`check_goals`,
  drawn with the seed within 4 m of the old ones) and one vehicle is dropped with land (the
  one nearest the fleet's centre whose landing spot is R clear of the goals), its motion
  flown as the ground station does (`landing_motion`: one step on at its acceleration,
  `DROP_COAST_STEPS`, then braking at 2 m/s^2 or the acceleration box, then down at
  0.7 m/s to 0.3 m above the floor; ``--coast-steps 0`` brakes at once);
- ``goals``: the same new goals, nobody dropped.

Each replan picks its own horizon (`replan_horizon`), as in flight. The figures per run:
seconds to a verified plan (wall, and the process's CPU time over all its threads: on a
loaded machine a wall time far above it is waiting), or the failure and its reason, attempts,
the separation kept (R, or a hair less from a state passing near R), the continuous-time
minimum separation and the closest approach to the fixed trajectory. Progress to stderr.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import planner  # noqa: E402
from gcs.fleet.fleetfile import FlightOptions  # noqa: E402
from gcs.flight.replan.prediction import BRAKING_DECELERATION  # noqa: E402
from planner.errors import ScenarioError  # noqa: E402
from planner.families.generators import circle_swap, grid_to_sphere, random_transitions  # noqa: E402
from planner.methods.replan import ReplanError, check_goals, plan_replan  # noqa: E402
from planner.model.fixed import DROP_COAST_STEPS, FixedTrajectory, landing_motion  # noqa: E402

#: The floors asked for (s): 16 vehicles mid-crossing, and 100 vehicles.
FLOORS = {16: 0.3, 100: 2.0}
#: The ground station's defaults (`gcs.flight.replan.replan`, `FlightOptions`).
DECELERATION = BRAKING_DECELERATION
LAND_SPEED = FlightOptions().land_speed
LANDING_HEIGHT = FlightOptions().landing_height
#: Share of the steered vehicles whose goal changes, and how far a new goal lies from the
#: old one at most, per axis (m): an operator moving a goal, not a new mission.
GOAL_SHARE = 0.25
GOAL_REACH = 4.0


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def source_scenario(family: str, size: int, seed: int) -> dict[str, Any]:
    if family == "circle":
        return circle_swap(size)
    if family == "random":
        # random128's box grows with the fleet: about 8 m^3 per vehicle, 4 m high
        side = max(10.0, float(np.sqrt(size * 8.0 / 4.0)))
        return random_transitions(size, size=(side, side, 4.0), seed=seed, steps=100)
    if family == "grid-sphere":
        return grid_to_sphere(size, seed=seed)
    raise ValueError(f"unknown family {family!r}")


def new_goals(base: planner.Scenario, ids: list[str], goals: np.ndarray, dropped: int | None,
              rest: np.ndarray | None, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """About `GOAL_SHARE` of the kept vehicles get a new goal drawn in the workspace within
    `GOAL_REACH` of the old one, valid for `check_goals` against every other goal and the
    dropped vehicle's resting point."""
    lim = base.limits
    keep = [n for n in range(len(ids)) if n != dropped]
    chosen = rng.choice(keep, size=max(1, round(GOAL_SHARE * len(keep))), replace=False)
    # every kept goal, the dropped vehicle's own (the variant without a drop keeps it) and
    # where it comes to rest (a key no vehicle has)
    others: dict[str, Any] = {ids[n]: goals[n] for n in range(len(ids))}
    if rest is not None:
        others[" rest"] = rest
    out: dict[str, np.ndarray] = {}
    floor = lim.position_min.copy()
    floor[2] += 1.0
    for n in chosen:
        vid = ids[int(n)]
        low = np.maximum(goals[n] - GOAL_REACH, floor + 0.5)
        high = np.maximum(np.minimum(goals[n] + GOAL_REACH, lim.position_max - 0.5), low)
        for _ in range(2000):
            candidate = low + (high - low) * rng.random(3)
            if rest is not None and np.linalg.norm(
                    (candidate - rest) / base.separation_scale) < base.min_separation + 0.2:
                continue
            try:
                out.update(check_goals(base, {vid: candidate},
                                       {k: v for k, v in {**others, **out}.items() if k != vid}))
            except ScenarioError:
                continue
            others.pop(vid, None)
            break
    return out


def drop_motion(base: planner.Scenario, vid: str, p: np.ndarray, v: np.ndarray,
                a: np.ndarray, coast_steps: int) -> FixedTrajectory:
    """The ground station's motion of a vehicle dropped with land (`_drop_motion`)."""
    lim = base.limits.acceleration_max
    deceleration = DECELERATION if lim is None else min(DECELERATION, float(np.min(lim[:2])))
    floor = float(base.limits.position_min[2]) + LANDING_HEIGHT
    return landing_motion(vid, p, v, base.dt, deceleration, LAND_SPEED, min(floor, float(p[2])),
                          acceleration=a, coast_steps=coast_steps)


def pick_drop(base: planner.Scenario, state: tuple[np.ndarray, ...], coast_steps: int
              ) -> tuple[int, FixedTrajectory]:
    """The dropped vehicle: the one nearest the fleet's centre (most in the others' way)
    whose landing spot is R clear of every other vehicle's goal (else no replan could keep
    R from it, and `plan_replan` refuses at once)."""
    p, v, a = state
    ids = list(base.ids)
    for n in np.argsort(np.linalg.norm(p - p.mean(axis=0), axis=1)):
        fixed = drop_motion(base, ids[n], p[n], v[n], a[n], coast_steps)
        others = np.delete(base.goals, n, axis=0)
        clear = np.linalg.norm((others - fixed.positions[-1]) / base.separation_scale, axis=1)
        if clear.min() >= base.min_separation:
            return int(n), fixed
    raise ValueError("every vehicle's landing spot lies within R of another's goal")


def replan_once(base: planner.Scenario, ids: list[str], state: tuple[np.ndarray, ...],
                goals: np.ndarray, changed: dict[str, np.ndarray],
                fixed: list[FixedTrajectory], dropped: int | None) -> dict[str, Any]:
    p, v, a = state
    keep = [n for n in range(len(ids)) if n != dropped]
    g = np.array([changed.get(ids[n], goals[n]) for n in keep])
    began = time.perf_counter()
    cpu = time.process_time()
    try:
        replan = plan_replan(base, [ids[n] for n in keep], p[keep], v[keep], a[keep], g,
                             fixed=fixed)
    except ReplanError as exc:
        return {"ok": False, "seconds": round(time.perf_counter() - began, 4),
                "error": str(exc)[:400]}
    verification = replan.plan.verification
    assert verification is not None
    return {
        "ok": replan.plan.ok,
        "seconds": round(replan.seconds, 4),
        "cpu_s": round(time.process_time() - cpu, 4),
        "attempts": replan.attempts,
        "horizon_s": round(replan.plan.scenario.horizon, 2),
        "iterations": len(replan.plan.iterations) - 1,
        "verified": verification.flyable and verification.separated
        and verification.within_bounds and verification.clear,
        "separation_kept": round(replan.separation, 5),
        "min_separation_continuous": verification.min_separation_continuous,
        "fixed_distance_min": verification.fixed_distance_min,
    }


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    times = [r["seconds"] for r in rows if r["ok"]]
    cpu = [r["cpu_s"] for r in rows if r["ok"]]
    return {"runs": len(rows), "verified": len(times),
            "median_s": round(statistics.median(times), 4) if times else None,
            "worst_s": round(max(times), 4) if times else None,
            "median_cpu_s": round(statistics.median(cpu), 4) if cpu else None,
            "worst_cpu_s": round(max(cpu), 4) if cpu else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--families", nargs="+", default=["circle", "random", "grid-sphere"])
    parser.add_argument("--sizes", type=int, nargs="+", default=[16, 50, 100])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--at", type=float, nargs="+", default=[0.25, 0.5, 0.75],
                        help="replan instants as shares of the source plan's horizon")
    parser.add_argument("--coast-steps", type=int, default=DROP_COAST_STEPS,
                        help="steps the dropped vehicle coasts before braking (0: at once)")
    parser.add_argument("--variants", nargs="+", default=["goals+drop", "goals"])
    args = parser.parse_args()
    load = list(os.getloadavg())
    runs: list[dict[str, Any]] = []
    sources: list[dict[str, Any]] = []
    for family in args.families:
        for size in args.sizes:
            # the circle has no randomness of its own: plan it once, vary the replans
            plans: dict[int, planner.Plan] = {}
            for seed in args.seeds:
                key = 0 if family == "circle" else seed
                if key not in plans:
                    began = time.perf_counter()
                    plans[key] = planner.plan(source_scenario(family, size, seed))
                    sources.append({"family": family, "vehicles": size, "seed": key,
                                    "status": plans[key].status,
                                    "seconds": round(time.perf_counter() - began, 2)})
                    log(f"{family} {size} seed {key}: source {plans[key].status} in "
                        f"{time.perf_counter() - began:.1f} s")
                source = plans[key]
                if not source.ok:
                    continue
                base = source.scenario
                ids = list(base.ids)
                for share in args.at:
                    t = share * base.horizon
                    state = tuple(x[:, 0] for x in source.sample(np.array([t])))
                    rng = np.random.default_rng([seed, size, round(1000 * share)])
                    dropped, fixed = pick_drop(base, state, args.coast_steps)
                    changed = new_goals(base, ids, base.goals, dropped, fixed.positions[-1],
                                        rng)
                    for variant in args.variants:
                        drop = variant == "goals+drop"
                        row = replan_once(base, ids, state, base.goals, changed,
                                          [fixed] if drop else [], dropped if drop else None)
                        runs.append({"family": family, "vehicles": size, "seed": seed,
                                     "at": share, "t_s": round(t, 2), "variant": variant,
                                     "goals_changed": len(changed),
                                     "dropped": ids[dropped] if drop else None, **row})
                        log(f"  seed {seed} at {share:g} {variant}: ok={row['ok']} "
                            f"{row['seconds']} s" + ("" if row["ok"] else
                                                     f" ({row['error'][:120]})"))
    summary: dict[str, Any] = {}
    for family in args.families:
        for size in args.sizes:
            for variant in args.variants:
                rows = [r for r in runs if r["family"] == family and r["vehicles"] == size
                        and r["variant"] == variant]
                if rows:
                    summary[f"{family}/{size}/{variant}"] = summarise(rows)
    by_size = {}
    for size in args.sizes:
        rows = [r for r in runs if r["vehicles"] == size]
        entry = summarise(rows)
        if size in FLOORS and entry["median_s"] is not None:
            entry["floor_s"] = FLOORS[size]
            entry["median_over_floor"] = round(entry["median_s"] / FLOORS[size], 3)
            entry["worst_over_floor"] = round(entry["worst_s"] / FLOORS[size], 3)
        mid = [r for r in rows if r["at"] == 0.5 and r["ok"]]
        if mid:
            entry["mid_crossing_median_s"] = round(statistics.median(
                r["seconds"] for r in mid), 4)
            entry["mid_crossing_worst_s"] = round(max(r["seconds"] for r in mid), 4)
            entry["mid_crossing_median_cpu_s"] = round(statistics.median(
                r["cpu_s"] for r in mid), 4)
        by_size[str(size)] = entry
    print(json.dumps({
        "benchmark": "replan",
        "command": "python " + " ".join(sys.argv),
        "coast_steps": args.coast_steps,
        "floors_s": {str(k): v for k, v in FLOORS.items()},
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "processor": platform.processor() or platform.machine()},
        "load_average_at_start": load,
        "load_average_at_end": list(os.getloadavg()),
        "by_size": by_size,
        "summary": summary,
        "sources": sources,
        "runs": runs,
    }, indent=2))


if __name__ == "__main__":
    main()
