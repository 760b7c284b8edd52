"""`fleetplan fleet land --plan PLAN.json --fleet FLEET.json`: land a hovering fleet by plan.

Every vehicle of the fleet must answer (its place is needed to plan around it); the chosen
ones (`--vehicle`, default all) in the air are landed, the others kept clear of.

A fleet whose station was lost is left hovering where their columns meet (the Hold failsafe:
`gcs.flight.procedure.failsafe`): landing those vehicles straight down (`fleet land`) would
bring them closer than R. This reads where every chosen vehicle is, plans a verified landing
from there under PLAN's workspace, obstacles and R (`planner.methods.landing.plan_landing`:
touchdown points R apart, clear of the vehicles already on the ground), and flies it as a
flight of its own (`FlightExecutor`: OFFBOARD from where each hovers, the landing plan as
setpoints, then the autopilot's Land at the touchdown points).
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from typing import Any

import numpy as np

from gcs import frames
from gcs.errors import GcsError
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS, VehicleLink
from gcs.flight.procedure import vehicle
from gcs.flight.run.executor import FlightExecutor
from gcs.wire import mavlink
from planner import Plan
from planner.methods.landing import LandingError, LandingPlan, plan_landing
from planner.model.fixed import FixedTrajectory

__all__ = ["FleetState", "land_by_plan", "landing_for", "read_fleet_state"]


class FleetState:
    """Where the fleet's vehicles are (world ENU) and which are in the air."""

    def __init__(self) -> None:
        self.flying: dict[str, np.ndarray] = {}
        self.grounded: dict[str, np.ndarray] = {}


async def read_fleet_state(fleet: FleetSpec, timeout: float) -> FleetState:
    """Every vehicle's position in the world frame (its home from the fleet file, or from its
    EKF origin and the fleet's world_origin) and whether it is in the air (armed and not
    reported on the ground); `GcsError` naming a vehicle that does not answer (a landing
    cannot be planned around a vehicle whose place is unknown)."""
    state = FleetState()
    async with LinkHub(decode_ids=DECODED_IDS) as hub:
        links: dict[str, VehicleLink] = {}
        for spec in fleet.vehicles:
            links[spec.id] = await hub.add(spec.id, spec.connection, spec.system_id,
                                           spec.component_id, signing_key=spec.signing_key,
                                           peer=spec.peer)
        for spec in fleet.vehicles:
            link = links[spec.id]
            await vehicle.connect(link, spec, timeout, armed_ok=True)  # its autopilot, streams
            if spec.home is not None:
                home = np.asarray(spec.home, dtype=float)
            else:
                assert fleet.world_origin is not None  # the fleet file demands one or the other
                home, _ = await vehicle.resolve_home(link, spec.id, fleet.world_origin)
            tel = link.telemetry
            assert tel.position_ned is not None  # waited for above
            where = frames.ned_to_world(tel.position_ned, home)
            airborne = tel.armed and tel.landed_state != mavlink.MAV_LANDED_STATE_ON_GROUND
            (state.flying if airborne else state.grounded)[spec.id] = where
    return state


def landing_for(plan: Plan, state: FleetState, chosen: list[str], landing_height: float
                ) -> LandingPlan:
    """The verified landing plan of the `chosen` vehicles in the air under `plan`'s
    scenario, clear of every other vehicle where it is, hovering or on the ground (fixed
    obstacles: the plan keeps R from them and its touchdown points keep R from their
    columns); `LandingError` when there is none."""
    ids = [vid for vid in state.flying if vid in chosen]
    p = np.array([state.flying[vid] for vid in ids])
    zeros = np.zeros_like(p)
    others = {**state.grounded, **{vid: where for vid, where in state.flying.items()
                                   if vid not in chosen}}
    fixed = [FixedTrajectory(vid, np.asarray(where, dtype=float)[None, :])
             for vid, where in others.items()]
    return plan_landing(plan.scenario, p, zeros, zeros, ids=ids,
                        landing_height=landing_height, fixed=fixed)


async def land_by_plan(plan: Plan, fleet: FleetSpec, chosen: list[str], timeout: float,
                       say: Any = print) -> int:
    """Read, plan, fly (see the module); the exit status: 0 when every vehicle that was in
    the air landed and disarmed, 1 when not, 2 when no landing plan was found."""
    state = await read_fleet_state(fleet, timeout)
    for vid, where in state.grounded.items():
        say(f"{vid}: on the ground at {np.round(where, 2).tolist()}")
    for vid in set(state.flying) - set(chosen):
        say(f"{vid}: in the air at {np.round(state.flying[vid], 2).tolist()}, not chosen: "
            f"landed around")
    if not set(state.flying) & set(chosen):
        say("nothing chosen in the air: nothing to land")
        return 0
    options = fleet.options.replace(where="fleet", at_end="land")
    try:
        landing = await asyncio.to_thread(landing_for, plan, state, chosen,
                                          options.landing_height)
    except LandingError as exc:
        print(f"no landing plan: {exc} (fleetplan fleet land without --plan lands each "
              f"straight down)", file=sys.stderr)
        return 2
    touchdowns = landing.plan.scenario.goals
    for vid, down in zip(landing.plan.scenario.ids, touchdowns, strict=True):
        say(f"{vid}: in the air at {np.round(state.flying[vid], 2).tolist()}, lands at "
            f"{np.round(down, 2).tolist()}")
    say(f"landing plan: {landing.plan.scenario.horizon:g} s, keeps {landing.separation:.2f} m "
        f"(R {plan.scenario.min_separation:g} m), planned in {landing.seconds:.2f} s")
    flight = FlightExecutor(landing.plan, fleet, options, take_over=True)
    task = flight.start()

    async def show() -> None:
        async for event in flight.events():
            if event["kind"] not in ("statustext", "mode_change"):
                say(f"  [{event['t']:7.2f}] {event['vehicle'] or 'fleet'}: {event['kind']} "
                    f"{event['detail']}")

    printer = asyncio.create_task(show())
    try:
        record = await task
    except GcsError as exc:
        print(f"landing flight failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    finally:
        await asyncio.wait([printer], timeout=1.0)
        printer.cancel()
    return 0 if record["summary"]["completed"] else 1


def run(args: argparse.Namespace, fleet: FleetSpec, chosen: list[str], timeout: float) -> int:
    """`fleet land --plan`: the exit status (2 for an unreadable plan, as `fly`)."""
    from gcs.cli.plan_file import read_plan

    try:
        plan = read_plan(args.plan, "fleet land --plan")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        return asyncio.run(land_by_plan(plan, fleet, chosen, timeout,
                                        lambda text: print(text, flush=True)))
    except GcsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
