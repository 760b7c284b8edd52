"""Plans that take off from or land on the ground, flown from the ground.

A show planned with `takeoff` / `landing` (`planner.methods.ground`) starts with its drones
parked on their homes (z = 0, at rest) and carries its own takeoff waves and landing legs.
The executor flies such a vehicle without a climb of its own: its boarding stops at the mode
that follows setpoints, disarmed on the ground (`Autopilot.ground_boarding`); it is armed
`ARM_LEAD_S` before its takeoff time in the plan (an autopilot disarms a vehicle that stands
armed on the ground for 10 s), leaves the ground at that time by its autopilot's way
(`Autopilot.liftoff`: PX4 on the plan's setpoints, ArduCopter by MAV_CMD_NAV_TAKEOFF to the
plan's height `TAKEOFF_AHEAD_S` later and the plan's setpoints once it is up), and at its
touchdown time its autopilot's land ends its flight on its slot (it disarms on the ground).
Takeoff and touchdown times are read off the trajectories (`planner.verification.ground`),
not taken from a claim in the plan file.

Refused before anything is armed: a vehicle that lands and takes off again within the
plan (it is armed once per flight), one that never leaves the ground, and a plan starting on
the ground for vehicles taken over in the air.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs import frames
from gcs.errors import GcsError, PlanRejected, PreflightFailed
from gcs.flight.link.setpoints import SetpointTrack
from gcs.flight.procedure import vehicle
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.endings import land_vehicle, wait_disarmed
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.run.boarding import arm_vehicle
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.stream import Streamer
from gcs.phases import EventKind, VehiclePhase
from planner import Plan
from planner.verification.ground import GROUND_TOLERANCE, airborne

__all__ = ["ARM_LEAD_S", "HANDOVER_M", "TAKEOFF_AHEAD_S", "GroundShow", "GroundSpan",
           "ground_refusal", "ground_spans"]

#: A vehicle standing on the ground is armed this long before its takeoff time (s): time
#: for the command and its confirmation, well inside the 10 s after which PX4
#: (COM_DISARM_PRFLT) and ArduCopter (DISARM_DELAY) disarm a vehicle that has not taken off.
ARM_LEAD_S = 2.0
#: A vehicle that takes off by command (`Autopilot.liftoff` ``takeoff``) is sent up to the
#: plan's height this long after its takeoff time (s) ...
TAKEOFF_AHEAD_S = 2.0
#: ... and given the plan's setpoints once it reports this height on its way (m): well off
#: the ground (ArduCopter has left its landed state by then), and climbing as the plan does.
HANDOVER_M = 1.0
#: How often a waiting vehicle looks at the flight clock again (s): a pause stops the clock.
_POLL_S = 0.5

#: Aborts the flight, with the reason (the executor's `request_abort` with land).
AbortCallback = Callable[[str], None]


@dataclass(frozen=True)
class GroundSpan:
    """When a vehicle leaves the ground and is down for good, in plan time (s); None: it
    starts (or ends) in the air."""

    liftoff: float | None
    touchdown: float | None


def ground_spans(plan: Plan) -> dict[str, GroundSpan] | str:
    """Each vehicle that starts or ends parked on the ground, by id, with its span; or why
    the plan cannot be flown from the ground (naming the vehicle and the fix). Only vehicles
    that reach z <= 0 are looked at closer: a plan in the air costs one pass over heights."""
    dt = plan.scenario.dt
    spans: dict[str, GroundSpan] = {}
    for track in plan.vehicles:
        p = track.position
        if p[:, 2].min() > GROUND_TOLERANCE:
            continue
        flying = airborne(p[None], track.velocity[None], track.acceleration[None])[0]
        steps = np.flatnonzero(flying)
        if len(steps) == 0:
            return (f"vehicle {track.id} stands on the ground for the whole plan: leave it "
                    f"out of the plan (and the fleet)")
        first, last = int(steps[0]), int(steps[-1])
        if len(steps) != last - first + 1:
            down = first + int(np.argmin(flying[first:last + 1]))
            up = down + int(np.argmax(flying[down:]))
            return (f"vehicle {track.id} lands at t={down * dt:.1f} s and takes off again at "
                    f"t={up * dt:.1f} s: this ground station arms a vehicle once per flight; "
                    f"keep it in the air there, or fly the two parts as two plans")
        liftoff = first * dt if p[0, 2] <= GROUND_TOLERANCE else None
        touchdown = (last + 1) * dt if p[-1, 2] <= GROUND_TOLERANCE else None
        if liftoff is not None or touchdown is not None:
            spans[track.id] = GroundSpan(liftoff, touchdown)
    return spans


def ground_refusal(plan: Plan, *, take_over: bool = False) -> str | None:
    """Why this ground station cannot fly `plan` from or to the ground (`ground_spans`), or
    with `take_over` (vehicles already in the air) a plan that starts on the ground; None
    when it can."""
    return _refusal(ground_spans(plan), take_over)


def _refusal(spans: dict[str, GroundSpan] | str, take_over: bool) -> str | None:
    if isinstance(spans, str):
        return f"refusing to fly the plan: {spans}"
    if take_over:
        starting = [vid for vid, span in spans.items() if span.liftoff is not None]
        if starting:
            return (f"refusing to fly the plan: vehicle {starting[0]} starts on the ground in "
                    f"it, but the vehicles taken over are in the air; plan from where they "
                    f"hover (fleetplan fleet land --plan makes such a plan)")
    return None


@dataclass
class GroundShow:
    """The flight's part in the vehicles that start or end on the ground (see the module);
    empty for a plan flown in the air."""

    spans: dict[str, GroundSpan]
    landed: set[str] = field(default_factory=set)
    """Vehicles its landing put down on their slot (the end of the flight leaves them be)."""

    @classmethod
    def of(cls, plan: Plan, *, take_over: bool = False) -> GroundShow:
        """`PlanRejected` with `ground_refusal`'s reason when it cannot be flown."""
        spans = ground_spans(plan)
        why = _refusal(spans, take_over)
        if why is not None:
            raise PlanRejected(why)
        assert not isinstance(spans, str)  # (a reason is a refusal)
        return cls(spans)

    def on_ground(self, v: VehicleStatus) -> bool:
        """Whether `v` starts parked on the ground and takes off by the plan."""
        span = self.spans.get(v.id)
        return span is not None and span.liftoff is not None

    def streams_from_start(self, v: VehicleStatus) -> bool:
        """Whether `v` gets the plan's setpoints from flight time 0 (not one that must take
        off by command first)."""
        return not self.on_ground(v) or v.autopilot.liftoff == "setpoints"

    def replan_refusal(self) -> str | None:
        """Why the flight is not replanned in the air: a show flown from the ground keeps its
        own takeoff and landing waves; None for a plan in the air."""
        if not self.spans:
            return None
        return ("a plan that takes off from or lands on the ground is not replanned in flight "
                "(its takeoff and landing waves are the plan's); abort lands every vehicle")

    async def board(self, vehicles: Sequence[VehicleStatus], context: FlightContext) -> None:
        """Before the flight clock starts: every vehicle on the ground stands at its place in
        the plan (`PreflightFailed` naming it otherwise), and those whose takeoff time is
        within `ARM_LEAD_S` of it are armed (again, for one an autopilot disarmed while
        another took long to arm)."""
        for v in vehicles:
            if self.on_ground(v):
                _check_at_home(v, context.options.start_tolerance)
        first = [v for v in vehicles if self.on_ground(v)
                 and (self.spans[v.id].liftoff or 0.0) < ARM_LEAD_S]
        for _ in range(2):
            await asyncio.gather(*(arm_vehicle(v, context) for v in first
                                   if not v.linked.telemetry.armed))

    async def fly(self, vehicles: Sequence[VehicleStatus], tracks: Sequence[SetpointTrack],
                  streamer: Streamer, clock: FlightClock, context: FlightContext,
                  abort: AbortCallback) -> None:
        """While the plan is flown: arm, lift off and land each vehicle at its times; a
        vehicle that cannot (arming or takeoff refused) aborts the flight with land."""
        async def one(v: VehicleStatus, track: SetpointTrack) -> None:
            try:
                await self._fly_one(v, track, streamer, clock, context)
            except GcsError as exc:
                with contextlib.suppress(GcsError):
                    abort(f"{v.id} could not take off with its wave: {exc}")

        await asyncio.gather(*(one(v, track) for v, track in zip(vehicles, tracks, strict=True)
                               if v.id in self.spans))

    async def _fly_one(self, v: VehicleStatus, track: SetpointTrack, streamer: Streamer,
                       clock: FlightClock, context: FlightContext) -> None:
        span = self.spans[v.id]
        if span.liftoff is not None:
            if not v.linked.telemetry.armed:
                await _until(clock, span.liftoff - ARM_LEAD_S)
                if not _flown(v):
                    return
                await arm_vehicle(v, context, timeout=ARM_LEAD_S)
            await _until(clock, span.liftoff)
            if not _flown(v):
                return
            await _lift_off(v, track, span.liftoff, streamer, clock, context)
        if span.touchdown is not None:
            await _until(clock, span.touchdown)
            if not _flown(v):
                return
            await land_vehicle(v, context)
            self.landed.add(v.id)
            await wait_disarmed([v], context)


def _flown(v: VehicleStatus) -> bool:
    """Whether `v` is still the plan's (not faulty, not dropped by the policy)."""
    return v.fault is None and v.dropped is None


async def _lift_off(v: VehicleStatus, track: SetpointTrack, t: float, streamer: Streamer,
                    clock: FlightClock, context: FlightContext) -> None:
    """`v` leaves the ground at plan time `t` by its autopilot's way (`Autopilot.liftoff`)."""
    emit = context.emit
    if v.autopilot.liftoff == "takeoff":
        v.phase = VehiclePhase.CLIMBING
        ahead = track.at(round((t + TAKEOFF_AHEAD_S) * track.rate)).position
        height = await vehicle.take_off(v.linked, -float(ahead[2]), up_at=HANDOVER_M,
                                        timeout=context.options.gather_timeout,
                                        stalls=context.stalls)
        while clock.pause is not None:  # paused meanwhile: it holds its takeoff height
            await asyncio.sleep(_POLL_S)
        streamer.assign(v.id, v.linked, track, clock.start_tick)
        emit(v.id, EventKind.CLIMB, f"took off with its wave at t={t:.1f} s (NAV_TAKEOFF to "
                                    f"{height:.2f} m), the plan's setpoints from "
                                    f"{HANDOVER_M:g} m up")
    else:
        emit(v.id, EventKind.CLIMB, f"lifts off with its wave at t={t:.1f} s on the plan's "
                                    f"setpoints")
    v.phase = VehiclePhase.FLYING


async def _until(clock: FlightClock, t: float) -> None:
    """Wait until flight time `t` (a pause stops the clock, and the wait with it)."""
    while True:
        now = clock.flight_time()
        assert now is not None
        if now >= t:
            return
        await asyncio.sleep(min(t - now, _POLL_S))


def _check_at_home(v: VehicleStatus, tolerance: float) -> None:
    """`PreflightFailed` unless `v` stands (horizontally) within `tolerance` of its place on
    the ground in the plan: it takes off from where it stands."""
    tel = v.linked.telemetry
    assert v.start_ned is not None and v.home is not None
    if tel.position_ned is None:
        raise PreflightFailed(v.id, ["no position reported: it cannot be placed on the "
                                     "plan's ground grid"])
    off = float(np.linalg.norm(np.asarray(tel.position_ned, dtype=float)[:2]
                               - v.start_ned[:2]))
    if off > tolerance:
        where = np.round(frames.ned_to_world(v.start_ned, v.home), 3)
        raise PreflightFailed(v.id, [
            f"it stands {off:.2f} m from its takeoff home {where[:2].tolist()} in the plan "
            f"(start_tolerance {tolerance:g} m): it takes off from where it stands; place it "
            f"there, or give that home in the fleet file"])
