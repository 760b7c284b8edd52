"""Arriving: at the plan's starts before the flight clock starts, and at the goals after the
plan (the last switched replan's) has ended.

Every wait here counts station-running time (`gcs.flight.link.station`): a stall of the station
does not use up a timeout, and a late wake-up is noted as a stall at once, so that the goal
errors judged next wait for it even before the monitor or the streamer saw it.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Sequence

from gcs.errors import VehicleTimeout
from gcs.flight.link.station import STALL_NOTE_S
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.replan import Replanner
from gcs.flight.run.state import RunningFlight
from gcs.flight.run.summary import goal_tolerance
from gcs.flight.safety.monitor import PERIOD
from gcs.phases import EventKind, VehiclePhase

__all__ = ["SETTLE_POLL_S", "fly_to_plan_end", "gather", "settle_at_goals",
           "vehicle_goal_tolerance"]

#: How often the hold at the goals looks again for vehicles still arriving (s).
SETTLE_POLL_S = 0.05


async def gather(flight: RunningFlight, vehicles: Sequence[VehicleStatus] | None = None) -> None:
    """Until every vehicle (or those of `vehicles`) has flown its climb and is within
    `start_tolerance` of its start (`VehicleTimeout` after `gather_timeout`)."""
    options = flight.options
    tol = options.start_tolerance
    clock = flight.context.clock  # the station's own stalls do not use up the timeout
    deadline = clock() + options.gather_timeout
    streamer = flight.streamer
    assert streamer is not None
    while True:
        waiting = []
        for v in flight.vehicles if vehicles is None else vehicles:
            if flight.ground.on_ground(v):  # at its start already (`GroundShow.board`)
                continue
            assignment = streamer.assignments.get(v.id)
            done = (assignment is not None
                    and streamer.tick - assignment.start_tick >= len(assignment.track) - 1)
            error = v.distance_ned(v.start_ned)
            if done and error <= tol:
                if v.phase != VehiclePhase.AT_START:
                    v.phase = VehiclePhase.AT_START
                    flight.context.emit(v.id, EventKind.AT_START, f"{error:.3f} m from start")
            else:
                waiting.append((v.id, error))
        if not waiting:
            return
        if clock() > deadline:
            vid, error = waiting[0]
            raise VehicleTimeout(vid, f"not within {tol:g} m of its start after "
                                      f"{options.gather_timeout:g} s ({error:.2f} m away)")
        await asyncio.sleep(PERIOD)


async def fly_to_plan_end(flight: RunningFlight, replanner: Replanner,
                          changed: asyncio.Event) -> None:
    """Until the flight's plan (the last switched replan's) has ended and the hold at the
    goals is over; `changed` is set when a replan switched (the end moved)."""
    stalls = flight.context.stalls
    while True:
        if not await _sleep_until_plan_end(flight, changed, 0.0):
            continue
        for v in flight.vehicles:
            if v.phase == VehiclePhase.FLYING:
                v.phase = VehiclePhase.HOLDING
        flight.context.emit(None, EventKind.HORIZON, "plan ended, holding at the goals")
        since = time.monotonic()
        if not await _sleep_until_plan_end(flight, changed, flight.options.hold_at_goal):
            continue
        # the hold lasts `hold_at_goal` of station-running time: a vehicle that got no
        # setpoints during a stall of the station is still catching up
        while (lost := stalls.overlap(since, checked := time.monotonic())) > 0:
            since = checked
            await asyncio.sleep(lost)
        segments = len(flight.flown.segments)
        while replanner.job is not None:  # a replan on its way switches or misses
            await asyncio.sleep(PERIOD)
        if len(flight.flown.segments) == segments:
            return


async def _sleep_until_plan_end(flight: RunningFlight, changed: asyncio.Event,
                                extra: float) -> bool:
    """Sleep until `extra` s of flight time after the flight's plan ends; False as soon as a
    replan switched meanwhile (the end moved). A late wake-up is noted as a stall of the
    station."""
    segments = len(flight.flown.segments)
    while len(flight.flown.segments) == segments:
        now = flight.clock.flight_time()
        assert now is not None
        end = flight.flown.horizon + extra
        if now >= end:
            return True
        changed.clear()
        due = time.monotonic() + (end - now)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(changed.wait(), end - now)
        woke = time.monotonic()
        if woke - due > STALL_NOTE_S:
            flight.context.stalls.note(due, woke)
    return False


def vehicle_goal_tolerance(flight: RunningFlight, v: VehicleStatus) -> float:
    """How close to its goal `v` must end, with the accuracy it reports now."""
    return goal_tolerance(flight.options, flight.fleet.position_error,
                          v.linked.telemetry.gps_h_acc)


async def settle_at_goals(flight: RunningFlight) -> float:
    """Hold on, up to `goal_settle_max`, while a healthy vehicle is not yet within its goal
    tolerance (the stream keeps it at its goal); returns how long it held on (s)."""
    started = time.monotonic()

    def arriving() -> list[VehicleStatus]:
        return [v for v in flight.vehicles if v.fault is None and v.dropped is None
                and not v.distance_ned(v.goal_ned) <= vehicle_goal_tolerance(flight, v)]

    waited = 0.0
    while waited < flight.options.goal_settle_max and arriving():
        await asyncio.sleep(SETTLE_POLL_S)
        waited = time.monotonic() - started
    return waited
