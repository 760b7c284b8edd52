"""Flying a landing plan: the planned, checked way down when a flight is stopped with `land`.

An abort with `land` (operator, Ctrl-C, the service stopping, a fault policy) used to send
every vehicle straight down with PX4's Land where it was, which can bring two vehicles
stacked above each other closer than R. `PlannedLanding.run` instead:

1. picks a switch tick `landing_plan_timeout` ahead, and every steerable vehicle's state at
   that tick: the setpoint its stream would send then (the plan's exact state, or its pause
   hold), converted to the world frame; a vehicle with a tracking error is planned from
   where it is measured;
2. plans the landing (`planner.landing.plan_landing`, verified) in a worker thread while
   the streams go on along the flying plan, which keeps R until the switch;
3. at the switch tick streams the landing plan as setpoints, like a plan (queued with
   `Streamer.switch`, so every setpoint before it is still the flying plan's); once the landing
   horizon has passed, every vehicle stands at its touchdown point `landing_height` above
   the workspace floor, and PX4's Land takes it down vertically (touchdown points are R
   apart, so no descent crosses another vehicle).

Vehicles that cannot be steered (link or heartbeat lost, out of OFFBOARD, estimate
invalid, already landing) get PX4's Land at once, and so does everyone when no verified
plan is ready before the switch tick (the planner failed for whatever reason, or was late):
the events say which (`landing_plan`, `landing_fallback`). Whatever happens, every vehicle
is handed to `secure` in the end.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field

import numpy as np

from gcs import frames
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.setpoints import hold_track, plan_tracks
from gcs.flight.link.station import StationStalls
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.flight.run.stream import Streamer
from gcs.phases import AIRBORNE, EventKind, VehiclePhase
from planner.landing import LandingError, LandingPlan, plan_landing
from planner.scenario import Scenario
from planner.types import FloatArray

__all__ = ["STEERABLE_FAULTS", "PlannedLanding"]

#: Faults after which a vehicle still follows setpoints (it can fly a landing plan, from
#: where it is measured).
STEERABLE_FAULTS = ("tracking_error",)
#: Vehicle phases in which a vehicle flies the plan (or holds on it) and can be re-planned.
FLYING_PHASES = (VehiclePhase.FLYING, VehiclePhase.HOLDING, VehiclePhase.FAULTY)
#: Ticks kept free between the plan being ready and its switch tick (to build the tracks).
SWITCH_MARGIN_TICKS = 1
#: After the landing horizon, PX4's Land takes over once the vehicles had this long to settle.
SETTLE_S = 0.3


@dataclass
class PlannedLanding:
    """One landing of a fleet by a landing plan (see the module)."""

    scenario: Scenario
    """The flying plan's scenario: workspace, boxes, R, step length."""
    vehicles: list[VehicleStatus]
    streamer: Streamer
    options: FlightOptions
    emit: Emit
    secure: Callable[[VehicleStatus], Awaitable[None]]
    """Leaves one vehicle safe with PX4's Land (`gcs.flight.procedure.vehicle.secure`: disarmed on
    the ground, or landing); its stream stops."""
    stalls: StationStalls
    steered: list[VehicleStatus] = field(default_factory=list)
    """The vehicles flying the landing plan (once switched)."""
    result: LandingPlan | None = None

    def steerable(self, v: VehicleStatus) -> str | None:
        """Why `v` cannot fly a landing plan, or None when it can."""
        if v.link is None or v.home is None:
            return "not connected"
        if v.fault is not None and v.fault not in STEERABLE_FAULTS:
            return f"fault {v.fault}"
        if v.phase not in FLYING_PHASES:
            return f"phase {v.phase}"
        if v.id not in self.streamer.assignments:
            return "not streaming"
        age = self.stalls.age(v.link.telemetry.message_time, time.monotonic())
        if not age <= self.options.link_timeout:
            return "link silent"
        return None

    def _state(self, v: VehicleStatus, tick: int, at: float) -> tuple[FloatArray, ...]:
        """(position, velocity, acceleration) in the world frame of `v` at `tick` (GCS
        instant `at`): its stream's setpoint then, or (a faulty one) where it is measured."""
        home = v.placed
        tel = v.linked.telemetry
        if v.fault is not None and tel.position_ned is not None \
                and tel.position_time is not None:
            velocity = np.asarray(tel.velocity_ned or (0.0, 0.0, 0.0), dtype=float)
            position = np.asarray(tel.position_ned) + velocity * (at - tel.position_time)
            return (frames.ned_to_world(position, home), frames.ned_vector_to_world(velocity),
                    np.zeros(3))
        assignment = self.streamer.assignments[v.id]
        sp = assignment.track.at(tick - assignment.start_tick)
        return (frames.ned_to_world(sp.position, home), frames.ned_vector_to_world(sp.velocity),
                frames.ned_vector_to_world(sp.acceleration))

    def eligible(self) -> list[VehicleStatus]:
        """The vehicles a landing plan can steer (the others get PX4's Land)."""
        return [v for v in self.vehicles if self.steerable(v) is None]

    async def run(self) -> None:
        """Land every vehicle: the steerable ones by a landing plan if one is ready in time,
        the rest (or all, when none is) by PX4's Land. Never raises; whatever happens (even
        cancellation), every vehicle is handed to `secure` once."""
        streamer = self.streamer
        rate = streamer.rate
        downs: list[asyncio.Future[None]] = []
        handed: set[str] = set()

        def down(v: VehicleStatus) -> None:
            handed.add(v.id)
            downs.append(asyncio.ensure_future(self.secure(v)))

        try:
            steer = self.eligible()
            for v in self.vehicles:
                if v in steer:
                    continue
                if v.phase in AIRBORNE and v.phase != VehiclePhase.LANDING:
                    self.emit(v.id, EventKind.LANDING_FALLBACK,
                              f"PX4 Land: cannot be steered ({self.steerable(v)})")
                down(v)
            if steer:
                ok = await self._fly(steer, rate)
                for v in (self.steered if ok else steer):
                    down(v)
                handed.update(v.id for v in steer)  # the rest were sent down meanwhile
        finally:
            for v in self.vehicles:
                if v.id not in handed:
                    down(v)
            await asyncio.gather(*downs, return_exceptions=True)

    async def _fly(self, steer: list[VehicleStatus], rate: float) -> bool:
        """Plan, switch, fly the landing plan; False (after freezing the streams) when no
        plan was ready in time, which the events say."""
        streamer = self.streamer
        bound = self.options.landing_plan_timeout
        switch = streamer.next_tick() + SWITCH_MARGIN_TICKS + math.ceil(bound * rate)
        switch_at = streamer.tick_time(switch)
        states = [self._state(v, switch, switch_at) for v in steer]
        positions, velocities, accelerations = (np.array([s[k] for s in states])
                                                for k in range(3))
        began = time.perf_counter()
        deadline = began + bound
        try:
            result = await asyncio.wait_for(asyncio.to_thread(
                plan_landing, self.scenario, positions, velocities, accelerations,
                ids=[v.id for v in steer], landing_height=self.options.landing_height,
                deadline=deadline), timeout=max(0.0, switch_at - time.monotonic()
                                               - SWITCH_MARGIN_TICKS / rate))
        except TimeoutError:
            return self._fallback(steer, f"no landing plan within {bound:g} s")
        except LandingError as exc:
            return self._fallback(steer, str(exc))
        except Exception as exc:  # any planning failure: PX4 Land, never stuck
            return self._fallback(steer, f"landing planning failed: "
                                         f"{type(exc).__name__}: {exc}")
        if time.monotonic() > switch_at - 0.5 / rate or streamer.tick >= switch:
            return self._fallback(steer, f"the landing plan came after its switch tick "
                                         f"({time.perf_counter() - began:.2f} s)")
        self.result = result
        homes = [v.placed for v in steer]
        tracks = plan_tracks(result.plan, homes, rate, self.options.yaw)
        for v, track in zip(steer, tracks, strict=True):
            link = streamer.assignments[v.id].link if v.id in streamer.assignments else None
            if link is None:
                continue  # sent down meanwhile (a fault policy)
            streamer.switch(v.id, link, track, switch)  # the flying plan streams until then
            v.phase = VehiclePhase.LANDING
            self.steered.append(v)
        horizon = result.plan.scenario.horizon
        verification = result.plan.verification
        kept = verification.min_separation_continuous if verification is not None else None
        self.emit(None, EventKind.LANDING_PLAN, (
            f"{len(self.steered)} vehicle(s) land by a verified plan from t+{bound:g} s: "
            f"touchdown in {horizon:.1f} s, closest {_figure(kept)} m (keeps at least "
            f"{result.separation:.2f} m), planned in {result.seconds:.3f} s"))
        end = switch_at + horizon + SETTLE_S
        while (left := end - time.monotonic()) > 0:
            await asyncio.sleep(left)
        return True

    def _fallback(self, steer: list[VehicleStatus], why: str) -> bool:
        """Freeze the streams where they are and say that PX4's Land takes over."""
        streamer = self.streamer
        for v in steer:
            assignment = streamer.assignments.get(v.id)
            if assignment is not None and assignment.last is not None:
                streamer.assign(v.id, assignment.link, hold_track(
                    assignment.last.position, assignment.last.yaw, streamer.rate))
        self.emit(None, EventKind.LANDING_FALLBACK,
                  f"PX4 Land for {', '.join(v.id for v in steer)}: {why}")
        return False


def _figure(x: float | None) -> str:
    return "?" if x is None else f"{x:.2f}"
