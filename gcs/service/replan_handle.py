"""A flight handle that also replans in flight and tells which plans the flight flies.

`ReplanHandle` is `gcs.flight.flight_handle.FlightHandle` (used the same way, from another
thread's loop) with two more requests run on the vehicle loop: `replan` starts
`FlightExecutor.replan` and answers its replan object; `replanned` gives the switched
replans' plans with their switch times (what `gcs.service.flown_trajectory` samples), read
from the executor's plans flown (`FlightExecutor.flown`). The REST service's vehicle host
and `fleetplan fly --control` drive their flights through it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from gcs.flight.fleetfile import FleetSpec, FlightOptions
from gcs.flight.flight_handle import SNAPSHOT_HZ, FlightHandle
from gcs.flight.vehicle_loop import VehicleLoop
from planner import Plan

__all__ = ["SWITCHED", "ReplanHandle", "Segment"]

#: The replan status of a replan whose plan is flown (`gcs.flight.phases.ReplanStatus`).
SWITCHED = "switched"


@dataclass(frozen=True)
class Segment:
    """One plan of a flight: flown from flight time `start` (its time 0)."""

    start: float
    plan: Plan
    replan: int | None = None
    """The replan's id; None for the mission's plan."""


class ReplanHandle(FlightHandle):
    """`FlightHandle` with in-flight replans; see the module."""

    @classmethod
    async def create(cls, vehicles: VehicleLoop, plan: Plan, fleet: FleetSpec,
                     options: FlightOptions | None = None, *,
                     on_event: Callable[[dict[str, Any]], None] | None = None,
                     snapshot_hz: float = SNAPSHOT_HZ) -> ReplanHandle:
        """`FlightHandle.create`, typed as this class."""
        handle = await super().create(vehicles, plan, fleet, options, on_event=on_event,
                                      snapshot_hz=snapshot_hz)
        assert isinstance(handle, ReplanHandle)
        return handle

    async def replan(self, goals: dict[str, list[float]] | None, drop: list[str],
                     drop_action: str, reason: str) -> dict[str, Any]:
        """Start an in-flight replan: its replan object (status planning), raised across as
        `StateConflict` / `FieldError`. The snapshot shows it once this returns."""
        executor: Any = self._executor  # FlightExecutor.replan (helper flight's branch)

        async def start() -> dict[str, Any]:
            try:
                return dict(await executor.replan(goals, drop, drop_action, reason))
            finally:
                self._snapshot = executor.snapshot()

        return await self._vehicles.call(start)

    async def replanned(self) -> list[Segment]:
        """Every switched replan's plan and switch time (flight time), in order."""
        executor: Any = self._executor  # .replans and .flown (helper flight's branch)

        def read() -> list[Segment]:
            switched = [r["id"] for r in executor.replans if r["status"] == SWITCHED]
            later = executor.flown.segments[1:]
            return [Segment(s.start, s.plan, rid) for s, rid in zip(later, switched, strict=False)]

        return await self._vehicles.run(read)
