"""Closest approach when the ground station dies, or loses one vehicle, on the mock with
PX4's real failsafe timings; prints one JSON document to stdout.

    python bench/station_loss.py                         # station lost, every plan, 4 instants
    python bench/station_loss.py --plans paper-circle4 --at 2 4 6 8
    python bench/station_loss.py --land-by-plan          # then land the hovering ones by plan
    python bench/station_loss.py --lost 2                # vehicle 2's link lost (land_all)
    python bench/station_loss.py --default-failsafe      # PX4's own 5 s and Land for every vehicle
    python bench/station_loss.py --columns               # plans that keep columns apart

Each plan (`planner/examples`, flown faster than the paper: `--steps`) is planned with the
SCP planner and flown on in-process mock vehicles (PX4's COM_OF_LOSS_T 1 s, COM_FAIL_ACT_T
5 s, MPC_LAND_SPEED 0.7 m/s; disarm 0.5 s after touchdown). Before arming the station sets
each vehicle's failsafe (`gcs.flight.procedure.failsafe`: Hold where the plan brings its
column within R of another's, else Land, COM_FAIL_ACT_T staggered by altitude layer;
`--default-failsafe` puts PX4's 5 s and Land back on every vehicle instead). At flight time
`--at` every vehicle's link is blackholed both ways: nothing the station sends arrives and
nothing reaches it, as when its process is killed (`--lost N`: only vehicle N's, under
policy land_all, the station landing the others around it). They are watched until every
vehicle that lands is down and the others hover, and `HOVER_WATCH_S` more; with
`--land-by-plan` a new station then lands the hovering ones by plan (`fleetplan fleet land
--plan`: `gcs.cli.land_plan`). The figures per run: the closest true pair distance (every
vehicle's true position in the mock, every 10 ms, while any vehicle of the pair is in the
air) against R, before and while landing by plan, the plan's most stacked columns
(`stacked_columns`), the vehicles hovering and landed, and whether every vehicle ended
disarmed on the ground.

Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import planner  # noqa: E402
from gcs.autopilot import px4  # noqa: E402
from gcs.cli.land_plan import land_by_plan  # noqa: E402
from gcs.fleet.fleetfile import FleetSpec, FlightOptions  # noqa: E402
from gcs.flight.procedure import failsafe  # noqa: E402
from gcs.flight.run import executor  # noqa: E402
from gcs.flight.run.executor import FlightExecutor  # noqa: E402
from gcs.flight.safety.margin import required_separation  # noqa: E402
from gcs.sim import MockFleet, homes_under  # noqa: E402
from gcs.sim.ports import free_udp_base, mock_fleet_ports, mock_port_offsets  # noqa: E402

MOCK = {"disarm_after_land": 0.5, "status_rate": 5.0}
OPTIONS = FlightOptions(hold_at_goal=0.5, prestream=0.3, climb_speed=2.0,
                        landing_plan_timeout=1.0)
#: `--columns`: plans whose vertical distances count a tenth, so every two vehicles stay
#: nearly R apart horizontally (their columns apart).
COLUMNS = [1.0, 1.0, 10.0]
#: Once every vehicle that lands has landed and the others hover, they are watched this
#: long more (s).
HOVER_WATCH_S = 5.0
#: The plans and their steps (0.2 s each: the paper's 30 s flown in 12-16 s).
PLANS = {"paper-circle4": 60, "paper-circle8": 80, "circle16": 80}


def plan_of(name: str, steps: int | None, columns: bool) -> planner.Plan:
    data = json.loads((ROOT / "planner" / "examples" / f"{name}.json").read_text())
    plan = planner.plan(planner.Scenario.from_dict(
        {**data, **({"steps": steps} if steps else {}),
         **({"separation_scale": COLUMNS} if columns else {})}))
    if not plan.ok:
        raise SystemExit(f"{name}: {plan.problems()}")
    return plan


async def one(plan: planner.Plan, at: float, lost: int | None, land: bool) -> dict[str, Any]:
    homes = homes_under(plan.scenario.starts)
    base = free_udp_base(mock_port_offsets(len(homes)))
    async with MockFleet(homes=homes, settle_time=0.5, **mock_fleet_ports(base, len(homes)),
                         **MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, OPTIONS)
        task = flight.start()
        while (flight.flight_time() or -1.0) < at and not task.done():
            await asyncio.sleep(0.02)
        cut = mock.vehicles if lost is None else [mock.vehicles[lost]]
        for v in cut:
            v.faults.loss = 1.0
        truth: list[np.ndarray] = []
        deadline = time.monotonic() + 60.0
        settled: float | None = None  # when the last lander disarmed and the rest hovered
        while time.monotonic() < deadline and (settled is None
                                               or time.monotonic() < settled + HOVER_WATCH_S):
            truth.append(np.array([v.true_position_world for v in mock.vehicles]))
            if settled is None and all(
                    not v.armed or (v.mode == px4.HOLD and v.config.offboard_loss_action
                                    == px4.OBL_HOLD) for v in mock.vehicles):
                settled = time.monotonic()
            await asyncio.sleep(0.01)
        task.cancel()
        with contextlib.suppress(BaseException):  # the flight's outcome is not the figure
            await task
        hovering = [vid for vid, v in zip(plan.scenario.ids, mock.vehicles, strict=True)
                    if v.armed and v.mode == px4.HOLD]
        out: dict[str, Any] = {"at": at, **closest_pair(plan, truth),
                               "hovering": hovering, "landed": _landed(mock),
                               "samples": len(truth)}
        if land and hovering:  # a new station lands them by plan (`fleetplan fleet land --plan`)
            for v in mock.vehicles:
                v.faults.loss = 0.0
            landing = asyncio.create_task(land_by_plan(plan, fleet, list(plan.scenario.ids),
                                                       10.0, say=lambda _text: None))
            after: list[np.ndarray] = []
            deadline = time.monotonic() + 60.0
            while not landing.done() and time.monotonic() < deadline:
                after.append(np.array([v.true_position_world for v in mock.vehicles]))
                await asyncio.sleep(0.01)
            status = await landing if landing.done() else None
            landing.cancel()
            out["landing_by_plan"] = {"exit": status, **closest_pair(plan, after),
                                      "landed": _landed(mock), "samples": len(after)}
        out["all_down"] = _landed(mock) == len(homes)
        return out


def _landed(mock: MockFleet) -> int:
    """How many vehicles are disarmed on the ground."""
    return sum(bool(not v.armed and v.true_position_world[2] < 0.05) for v in mock.vehicles)


def closest_pair(plan: planner.Plan, truth: list[np.ndarray]) -> dict[str, Any]:
    """The closest true pair distance (the plan's metric) in `truth` while either of the
    pair is in the air, and the pair."""
    scale = np.asarray(plan.scenario.separation_scale)
    i, j = np.triu_indices(len(plan.scenario.ids), k=1)
    closest, where = np.inf, None
    for p in truth:
        air = (p[i, 2] > 0.05) | (p[j, 2] > 0.05)
        if not air.any():
            continue
        d = np.linalg.norm((p[i] - p[j]) / scale, axis=1)
        d[~air] = np.inf
        k = int(np.argmin(d))
        if d[k] < closest:
            closest, where = float(d[k]), (plan.scenario.ids[i[k]], plan.scenario.ids[j[k]])
    return {"closest_m": round(closest, 3) if np.isfinite(closest) else None, "pair": where}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--plans", nargs="+", default=list(PLANS), choices=list(PLANS))
    parser.add_argument("--at", nargs="+", type=float, default=[2.0, 4.0, 6.0, 8.0])
    parser.add_argument("--lost", type=int, default=None,
                        help="blackhole only this vehicle (index) under land_all")
    parser.add_argument("--columns", action="store_true",
                        help=f"plan with separation_scale {COLUMNS}: columns apart")
    parser.add_argument("--land-by-plan", action="store_true",
                        help="then land the hovering vehicles by plan from a new station")
    parser.add_argument("--default-failsafe", action="store_true",
                        help="PX4's own COM_FAIL_ACT_T (5 s) and Land on every vehicle")
    args = parser.parse_args()
    if args.default_failsafe:
        executor.layer_delays = lambda plan, speed: [5.0] * len(plan.scenario.ids)  # type: ignore[assignment]
        executor.column_conflicts = lambda plan, clearance: {}  # type: ignore[assignment]
    out: dict[str, Any] = {"case": "vehicle lost" if args.lost is not None else "station lost",
                           "failsafe": "px4 default" if args.default_failsafe
                           else "land by layer",
                           "columns_meet": "land" if args.default_failsafe else "hold",
                           "separation_scale": COLUMNS if args.columns else "the plan's",
                           "plans": {}}
    for name in args.plans:
        plan = plan_of(name, PLANS[name], args.columns)
        r = plan.scenario.min_separation
        stacked = failsafe.stacked_columns(plan, required_separation(plan.scenario))
        runs = []
        for at in args.at:
            print(f"{name} at {at:g} s", file=sys.stderr, flush=True)
            runs.append(asyncio.run(one(plan, at, args.lost, args.land_by_plan)))
        out["plans"][name] = {
            "vehicles": len(plan.scenario.ids), "horizon_s": plan.scenario.horizon, "R": r,
            "stacked_columns": None if stacked is None else {
                "lower": stacked[0], "upper": stacked[1], "horizontal_m": round(stacked[2], 3),
                "t": stacked[3]},
            "runs": runs,
            "closest_m": min(run["closest_m"] for run in runs),
            "kept_r_minus_5cm": all(run["closest_m"] >= r - 0.05 for run in runs)}
        landings = [run["landing_by_plan"] for run in runs if "landing_by_plan" in run]
        if landings:
            out["plans"][name]["landing_by_plan"] = {
                "closest_m": min(landing["closest_m"] for landing in landings),
                "all_landed": all(landing["landed"] == len(plan.scenario.ids)
                                  for landing in landings),
                "kept_r_minus_5cm": all(landing["closest_m"] >= r - 0.05
                                        for landing in landings)}
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
