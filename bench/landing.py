"""Landing-plan benchmark: how long `planner.methods.landing.plan_landing` takes from a flying
fleet's
state, for 8, 100 and 1,000 vehicles; prints one JSON document to stdout.

    python bench/landing.py                          # the default cases below
    python bench/landing.py --sizes 8 100 --seeds 0 1 2 --times 5 10 15 20

States come from real plans, sampled mid-flight (positions, velocities, accelerations):
the paper's 8-vehicle circle swap (8), and random crowds at random128's density
(`planner.families.generators.random_dense`, 100 and 1,000 vehicles, one plan per seed); for 1,000
vehicles planning the crowd itself takes a while (see docs/benchmarks/planner.md), so
`--crowd-states N...` samples random crowd states instead for those sizes (positions
1.2 R apart, random horizontal velocities up to 0.5 m/s per axis). Each landing is planned
once per state (a landing is planned once, in flight); the figures are the time to a
verified plan and whether it is within the ground station's bound (0.5 s by default,
`landing_plan_timeout`). Progress goes to stderr.
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

import numpy as np  # noqa: E402

import planner  # noqa: E402
from planner.families.generators import random_dense  # noqa: E402
from planner.methods.landing import LandingError, plan_landing  # noqa: E402

EXAMPLES = ROOT / "planner" / "examples"
#: The ground station's default bound on planning a landing (`FlightOptions`).
BOUND_S = 0.5


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def source_plan(size: int, seed: int) -> planner.Plan:
    """The flying plan the states are taken from: the paper circle for 8, else a crowd."""
    if size == 8:
        data = json.loads((EXAMPLES / "paper-circle8.json").read_text())
    else:
        data = random_dense(size, seed=seed)
    began = time.perf_counter()
    plan = planner.plan(data)
    log(f"  source plan {plan.scenario.name}: {plan.status} in "
        f"{time.perf_counter() - began:.1f} s")
    return plan


def crowd_state(size: int, seed: int) -> tuple[planner.Scenario, np.ndarray, np.ndarray]:
    """A random crowd in flight: random128's density, random horizontal velocities up to
    0.5 m/s per axis (a vertical one near the floor may have no way to stop in time)."""
    scenario = planner.Scenario.from_dict(random_dense(size, seed=seed))
    rng = np.random.default_rng(seed)
    velocities = rng.uniform(-0.5, 0.5, (size, 3))
    velocities[:, 2] = 0.0
    return scenario, scenario.starts, velocities


def land_once(scenario: planner.Scenario, p: np.ndarray, v: np.ndarray, a: np.ndarray
              ) -> dict[str, Any]:
    began = time.perf_counter()
    try:
        landing = plan_landing(scenario, p, v, a)
    except LandingError as exc:
        return {"ok": False, "seconds": round(time.perf_counter() - began, 4),
                "error": str(exc)[:300]}
    plan = landing.plan
    verification = plan.verification
    assert verification is not None
    return {
        "ok": plan.ok,
        "seconds": round(landing.seconds, 4),
        "within_bound": landing.seconds <= BOUND_S,
        "attempts": landing.attempts,
        "horizon_s": round(plan.scenario.horizon, 2),
        "iterations": len(plan.iterations) - 1,
        "separation_kept": round(landing.separation, 5),
        "min_separation_continuous": verification.min_separation_continuous,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[8, 100, 1000])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--times", type=float, nargs="+", default=[5.0, 12.0, 20.0],
                        help="flight times (s) the states are sampled at")
    parser.add_argument("--crowd-states", type=int, nargs="*", default=[],
                        help="sizes whose states are random crowds rather than plans")
    args = parser.parse_args()
    cases = []
    for size in args.sizes:
        for seed in args.seeds if size != 8 else [0]:
            log(f"{size} vehicles, seed {seed}")
            if size in args.crowd_states:
                scenario, p, v = crowd_state(size, seed)
                row = land_once(scenario, p, v, np.zeros_like(v))
                cases.append({"vehicles": size, "seed": seed, "state": "random crowd", **row})
                log(f"  crowd: {row['seconds']} s ok={row['ok']}")
                continue
            source = source_plan(size, seed)
            for t in args.times:
                p, v, a = (x[:, 0] for x in source.sample(np.array([t])))
                row = land_once(source.scenario, p, v, a)
                cases.append({"vehicles": size, "seed": seed,
                              "state": f"{source.scenario.name} at t={t:g} s", **row})
                log(f"  t={t:g}: {row['seconds']} s ok={row['ok']}")
    summary = {}
    for size in args.sizes:
        times = [c["seconds"] for c in cases if c["vehicles"] == size]
        oks = [c["ok"] for c in cases if c["vehicles"] == size]
        if times:
            summary[str(size)] = {"median_s": round(statistics.median(times), 4),
                                  "max_s": round(max(times), 4), "cases": len(times),
                                  "verified": sum(oks)}
    print(json.dumps({
        "benchmark": "landing",
        "bound_s": BOUND_S,
        "load_average_at_start": list(os.getloadavg()),
        "cpus": os.cpu_count(),
        "summary": summary,
        "cases": cases,
    }, indent=2))


if __name__ == "__main__":
    main()
