"""Making a fleet safe: every vehicle to land or hold after an abort or an error, by a landing
plan where one is flown.

An abort with land (or an error) while the plan is flown flies a verified landing plan first
(`gcs.flight.safety.landing`): planned from the plan's state `landing_plan_timeout` ahead,
streamed like the plan, then the autopilot's Land at the touchdown points; Land straight away
for vehicles that cannot be steered, or for all when no plan is ready in time. Otherwise every
stream freezes where it is and each vehicle is secured on its own (`endings.secure`: disarmed
on the ground, Land or Hold in the air). The end of a completed flight lands by a plan too
when straight descents would not keep R (`Securing.end_landing`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Any

from gcs.flight.procedure import endings
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.run.state import RunningFlight
from gcs.flight.safety.descent import DescentConflict
from gcs.flight.safety.landing import PlannedLanding
from gcs.phases import AIRBORNE, EventKind, VehiclePhase

__all__ = ["Securing"]


class Securing:
    """A flight's securing: one per action under way (see the module)."""

    def __init__(self, flight: RunningFlight) -> None:
        self.flight = flight
        self.landing: PlannedLanding | None = None
        """The landing plan being flown (after an abort with land, or at the end); the
        monitor goes on while it flies."""
        self._task: asyncio.Future[Any] | None = None
        self._action: str | None = None
        """The action `_task` secures the vehicles with (land or hold)."""

    async def secure_all(self, action: str) -> None:
        """Every vehicle to `action` (one securing per action: a land that overrides a hold
        under way starts once the hold's commands were answered)."""
        if self._task is None or self._action != action:
            previous = self._task
            self._action = action
            self._task = asyncio.ensure_future(self._secure_after(previous, action))
        await asyncio.shield(self._task)

    async def make_safe(self) -> None:
        """After an error or abort: secure everyone (again if a land overrode a hold
        meanwhile), wait for landed vehicles to disarm."""
        flight = self.flight
        while True:
            action = flight.aborting[0] if flight.aborting is not None else "land"
            await self.secure_all(action)
            if flight.aborting is None or flight.aborting[0] == action:
                break
        if action == "land":
            await endings.wait_disarmed([v for v in flight.vehicles if v.arm_sent],
                                        flight.context)
        for v in flight.vehicles:
            if (v.link is not None and v.link.telemetry.armed
                    and v.phase != VehiclePhase.HOVERING):
                flight.context.emit(v.id, EventKind.STILL_ARMED,
                                    "still armed: operator attention required")

    def end_landing(self, live: list[VehicleStatus],
                    descent: Callable[[VehicleStatus], list[DescentConflict] | None]
                    ) -> PlannedLanding | None:
        """The landing plan for `at_end: land` when a vehicle's straight descent from its
        goal would come closer than R to another's goal (`descent`: goals stacked above each
        other), or a vehicle off the plans is still in the air (it is planned around), or
        None: then Land takes each straight down, which keeps R."""
        flight = self.flight
        if flight.options.landing != "planned" or flight.streamer is None:
            return None
        around = [v for v in flight.vehicles if v not in live and v.phase in AIRBORNE]
        if not around and all(descent(v) == [] for v in live):
            return None
        landing = PlannedLanding(flight.plan.scenario.assigned(), live, flight.streamer,
                                 flight.context, self._land, flight.flown, flight.clock,
                                 around)
        return landing if landing.eligible() else None

    async def fly(self, landing: PlannedLanding) -> None:
        """Fly `landing` (the monitor keeps watching meanwhile)."""
        self.landing = landing
        await landing.run()

    def _planned_landing(self, action: str) -> PlannedLanding | None:
        """The landing plan's run for an abort with land, or None when nothing flies the
        plan (or `landing` is px4): then every vehicle gets Land where it is."""
        flight = self.flight
        if action != "land" or flight.options.landing != "planned" or flight.streamer is None:
            return None
        landing = PlannedLanding(flight.plan.scenario.assigned(), flight.vehicles,
                                 flight.streamer, flight.context, self._secure_one,
                                 flight.flown, flight.clock)
        return landing if landing.eligible() else None

    async def _secure_after(self, previous: asyncio.Future[Any] | None, action: str) -> None:
        if previous is not None:
            await asyncio.gather(previous, return_exceptions=True)
        if landing := self._planned_landing(action):
            await self.fly(landing)
        else:
            # Freeze every stream where it is, so nothing moves on along the plan meanwhile.
            # (An abort can come before run() made the streamer: then nothing streams, and
            # `secure` skips the vehicles, none of which has a link yet.)
            flight = self.flight
            if flight.streamer is not None:
                flight.streamer.freeze()
            await asyncio.gather(
                *(endings.secure(v, action, flight.context) for v in flight.vehicles),
                return_exceptions=True)

    def _land(self, v: VehicleStatus) -> Awaitable[None]:
        return endings.land_vehicle(v, self.flight.context)

    def _secure_one(self, v: VehicleStatus) -> Awaitable[None]:
        return endings.secure(v, "land", self.flight.context)
