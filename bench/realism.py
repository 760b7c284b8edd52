"""What a flight on the PX4-like mock measures: tracking error, separation flown, goal errors.

Plans the API tests' 4-vehicle crossing (SHORT_CROSSING, R = 1 m) twice: as is, and for a
fleet with position_error 0.25 m (R + 2 x 0.25 = 1.5 m), and flies each on 4 mock vehicles
with `realism="px4"` (PX4 v1.16 SIH SITL's estimate noise and lag, `gcs.sim`) through
`FlightExecutor`, once per seed. Prints one JSON document: per flight the summary's figures
(completed, goal errors, tracking error, separation measured against planned and required),
and their medians and ranges over the seeds, next to the figures measured on real PX4 SITL
(the PX4 SITL flight in the platform notes). Real time: about 25 s a flight.

    python bench/realism.py                 # seeds 0..4
    python bench/realism.py --seeds 3 --ideal   # also the ideal mock, for comparison
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import sys
from pathlib import Path
from typing import Any

# Run as `python bench/realism.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gcs.errors import GcsError
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety.margin import scenario_for_fleet
from gcs.sim import MockFleet, homes_under
from gcs.sim.ports import free_mock_fleet_ports
from planner import plan as make_plan
from tests.api.support import SHORT_CROSSING

#: The 4-vehicle crossing on PX4 v1.16 SIH SITL (R = 1 m, no margin).
PX4_SITL = {"goal_error_m": [0.04, 0.27], "tracking_error_max_m": 0.42,
            "min_separation_measured_m": [0.81, 0.96], "min_separation_planned_m": 1.0}


async def _fly(plan: Any, realism: str, seed: int, position_error: float | None
               ) -> dict[str, Any]:
    homes = homes_under(plan.scenario.starts)
    ports = free_mock_fleet_ports(len(homes))
    async with MockFleet(homes=homes, realism=realism, seed=seed, **ports) as mock:
        fleet = mock.fleet_dict(plan.scenario.ids)
        if position_error is not None:
            fleet["position_error"] = position_error
        executor = FlightExecutor(plan, FleetSpec.from_dict(fleet),
                                  FlightOptions(hold_at_goal=1.0))
        try:
            record = await executor.run()
        except GcsError:  # aborted or failed: its record says why
            record = executor.record
    s = record["summary"]
    detail = next((e["detail"] for e in record["events"] if e["kind"] == "goal_errors"), "")
    goals = [float(item.split()[1]) for item in detail.split(", ") if item]
    return {"seed": seed, "realism": realism, "completed": s["completed"], "why": s["why"],
            "goal_errors_m": goals, "goal_tolerance_m": s["goal_tolerance"],
            "tracking_error_max_m": s["tracking_error_max"],
            "min_separation_measured_m": s["min_separation_measured"],
            "min_separation_planned_m": s["min_separation_planned"],
            "min_separation_required_m": s["min_separation_required"]}


def _stats(all_flights: list[dict[str, Any]]) -> dict[str, Any]:
    flights = [f for f in all_flights if f["goal_errors_m"]]  # flown to the end
    if not flights:
        return {"flights": len(all_flights), "completed": 0}

    def med(key: str) -> float:
        return round(statistics.median(f[key] for f in flights), 3)

    goals = [g for f in flights for g in f["goal_errors_m"]]
    return {"flights": len(all_flights), "flown_to_the_end": len(flights),
            "completed": sum(f["completed"] for f in flights),
            "tracking_error_max_m": {"median": med("tracking_error_max_m"),
                                     "max": round(max(f["tracking_error_max_m"]
                                                      for f in flights), 3)},
            "min_separation_measured_m": {
                "median": med("min_separation_measured_m"),
                "min": round(min(f["min_separation_measured_m"] for f in flights), 3)},
            "min_separation_planned_m": med("min_separation_planned_m"),
            "goal_error_m": {"median": round(statistics.median(goals), 3),
                             "min": round(min(goals), 3), "max": round(max(goals), 3)}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="flights per case (default 5)")
    parser.add_argument("--ideal", action="store_true", help="also fly the ideal mock")
    args = parser.parse_args()
    cases = {"R1": (SHORT_CROSSING, None),
             "R1_position_error_0.25": (scenario_for_fleet(SHORT_CROSSING, 0.25), 0.25)}
    realisms = ["px4", "ideal"] if args.ideal else ["px4"]
    out: dict[str, Any] = {"machine": {"python": platform.python_version(),
                                       "cpus": os.cpu_count(),
                                       "load_average": list(os.getloadavg())},
                           "px4_sitl": PX4_SITL, "cases": {}}
    for name, (scenario, error) in cases.items():
        plan = make_plan(scenario)
        for realism in realisms:
            flights = [asyncio.run(_fly(plan, realism, seed, error))
                       for seed in range(args.seeds)]
            out["cases"][f"{name}/{realism}"] = {"summary": _stats(flights),
                                                 "flights": flights}
    out["machine"]["load_average_after"] = list(os.getloadavg())
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
