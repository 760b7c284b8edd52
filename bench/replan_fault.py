"""Policy ``replan`` against ``land_faulty`` on the same fault, on the mock; prints one JSON
document to stdout.

    python bench/replan_fault.py                    # both cases, both policies, once
    python bench/replan_fault.py --runs 3

Each case is planned with the SCP planner and flown on in-process mock vehicles; at flight
time 1 s one vehicle's link is cut (it stops talking, still listens: the GCS flags it after
`link_timeout`). The figures per run: how the flight ended, the closest true distance of
the faulty vehicle to any other (every vehicle's true position in the mock, sampled every
10 ms from the cut to the end) and of any pair, the replan's planning time and status, and
the vehicles that reached their goals. Cases:

- ``under``: the faulty vehicle hovers 1.5 m above another's path, 0.6 m beside it: its
  descent is in that vehicle's way;
- ``line8``: eight vehicles 1.5 m apart flying side by side; the fourth one's link is cut.

``--operator`` instead flies 16 vehicles side by side and asks, at flight time 2 s, for one
replan: four new goals and one vehicle dropped with land; the figures are its planning
time, the time from the request to the switch tick, and the closest true pair distance.

Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import planner  # noqa: E402
from gcs.fleet.fleetfile import FleetSpec, FlightOptions  # noqa: E402
from gcs.flight.run.executor import FlightExecutor  # noqa: E402
from gcs.sim import MockFleet, homes_under  # noqa: E402
from gcs.sim.ports import free_mock_fleet_ports  # noqa: E402

#: The mock lands at 1 m/s and disarms 0.5 s after touchdown (PX4 parameters it mimics).
MOCK = {"land_speed": 1.0, "disarm_after_land": 0.5, "status_rate": 5.0}
OPTIONS = FlightOptions(hold_at_goal=0.5, prestream=0.3, climb_speed=2.0, land_speed=1.0)
LIMITS = {"velocity_max": [3.0, 3.0, 3.0], "acceleration_max": [4.0, 4.0, 4.0]}

CASES: dict[str, tuple[dict[str, Any], int]] = {
    "under": ({
        "name": "under", "dt": 0.2, "steps": 50, "min_separation": 1.0,
        "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [10.0, 6.0, 4.0],
                   **LIMITS},
        "vehicles": [{"id": "uav1", "start": [1.0, 3.0, 1.0], "goal": [9.0, 3.0, 1.0]},
                     {"id": "uav2", "start": [5.0, 3.6, 2.5], "goal": [5.5, 3.6, 2.5]},
                     {"id": "uav3", "start": [1.0, 1.0, 1.0], "goal": [9.0, 1.0, 1.0]}],
    }, 1),
    "line8": ({
        "name": "line8", "dt": 0.2, "steps": 40, "min_separation": 1.0,
        "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [14.0, 4.0, 5.0],
                   **LIMITS},
        "vehicles": [{"id": f"uav{i + 1}", "start": [1.0 + 1.5 * i, 1.0, 1.0],
                      "goal": [1.0 + 1.5 * i, 3.0, 1.0]} for i in range(8)],
    }, 3),
}


async def _fly(plan: Any, policy: str, faulty: int) -> dict[str, Any]:
    homes = homes_under(plan.scenario.starts)
    ports = free_mock_fleet_ports(len(homes))
    async with MockFleet(homes=homes, settle_time=0.5, **ports, **MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, OPTIONS.replace(policy=policy))
        task = flight.start()
        while (flight.flight_time() or -1.0) < 1.0 and not task.done():
            await asyncio.sleep(0.02)
        mock.vehicles[faulty].faults.silent = True
        samples = []
        while not task.done():
            samples.append(np.array([v.true_position_world for v in mock.vehicles]))
            await asyncio.sleep(0.01)
        try:
            await task
            ending = "ran to its end"
        except Exception as exc:
            ending = f"{type(exc).__name__}: {exc}"
        record = flight.record
        assert record is not None
        truth = np.stack(samples)  # (T, N, 3)
        others = np.delete(truth, faulty, axis=1)
        to_faulty = np.linalg.norm(others - truth[:, faulty:faulty + 1], axis=2)
        i, j = np.triu_indices(truth.shape[1], k=1)
        pairs = np.linalg.norm(truth[:, i] - truth[:, j], axis=2)
        arrived = [vid for n, (vid, v) in enumerate(zip(plan.scenario.ids, mock.vehicles,
                                                          strict=True))
                   if n != faulty and np.linalg.norm(v.position_world[:2]
                                                     - plan.scenario.goals[n][:2]) < 0.2]
        replans = [{k: r[k] for k in ("status", "planning_s", "lead_s", "why")}
                   for r in record.get("replans", [])]
        return {"policy": policy, "ending": ending,
                "completed": record["summary"]["completed"],
                "closest_to_faulty_m": round(float(to_faulty.min()), 3),
                "closest_pair_m": round(float(pairs.min()), 3),
                "arrived": arrived, "replans": replans}


#: 16 vehicles 1.5 m apart; the operator's replan: four new goals, uav10 dropped.
LINE16 = {
    "name": "line16", "dt": 0.2, "steps": 40, "min_separation": 1.0,
    "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [26.0, 4.0, 5.0], **LIMITS},
    "vehicles": [{"id": f"uav{i + 1}", "start": [1.0 + 1.5 * i, 1.0, 1.0],
                  "goal": [1.0 + 1.5 * i, 3.0, 1.0]} for i in range(16)],
}
OPERATOR_GOALS = {"uav3": [4.0, 3.5, 2.0], "uav8": [10.0, 0.5, 1.5],
                  "uav12": [17.5, 0.5, 2.0], "uav15": [22.0, 0.5, 2.5]}


async def _operator(plan: Any) -> dict[str, Any]:
    homes = homes_under(plan.scenario.starts)
    ports = free_mock_fleet_ports(len(homes))
    async with MockFleet(homes=homes, settle_time=0.5, **ports, **MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, OPTIONS)
        task = flight.start()
        while (flight.flight_time() or -1.0) < 2.0 and not task.done():
            await asyncio.sleep(0.02)
        await flight.replan(OPERATOR_GOALS, ["uav10"], "land", "bench")
        samples = []
        while not task.done():
            samples.append(np.array([v.true_position_world for v in mock.vehicles]))
            await asyncio.sleep(0.01)
        record = await task
        truth = np.stack(samples)
        i, j = np.triu_indices(truth.shape[1], k=1)
        replan = record["replans"][0]
        return {"vehicles": len(plan.vehicles), "completed": record["summary"]["completed"],
                **{k: replan[k] for k in ("status", "lead_s", "planning_s",
                                          "request_to_switch_s", "horizon")},
                "closest_pair_m": round(float(np.linalg.norm(truth[:, i] - truth[:, j],
                                                             axis=2).min()), 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--cases", nargs="+", default=list(CASES))
    parser.add_argument("--operator", action="store_true",
                        help="the 16-vehicle operator replan instead of the fault cases")
    args = parser.parse_args()
    out: dict[str, Any] = {"runs": []}
    if args.operator:
        plan = planner.plan(planner.Scenario.from_dict(LINE16))
        assert plan.ok, plan.problems()
        for run in range(args.runs):
            result = asyncio.run(_operator(plan)) | {"run": run}
            print(json.dumps(result), file=sys.stderr)
            out["runs"].append(result)
        json.dump(out, sys.stdout, indent=1)
        print()
        return
    for name in args.cases:
        data, faulty = CASES[name]
        plan = planner.plan(planner.Scenario.from_dict(data))
        assert plan.ok, plan.problems()
        for policy in ("land_faulty", "replan"):
            for run in range(args.runs):
                began = time.perf_counter()
                result = asyncio.run(_fly(plan, policy, faulty))
                result |= {"case": name, "run": run, "vehicles": len(plan.vehicles),
                           "faulty": plan.scenario.ids[faulty],
                           "wall_s": round(time.perf_counter() - began, 1)}
                print(json.dumps(result), file=sys.stderr)
                out["runs"].append(result)
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
