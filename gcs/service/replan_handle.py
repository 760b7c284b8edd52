"""A flight handle that also tells which plans the flight flies.

`ReplanHandle` is `gcs.flight.host.flight_handle.FlightHandle` (used the same way, from another
thread's loop; its `replan` starts `FlightExecutor.replan`) with one more request run on the
vehicle loop: `replanned` gives the switched replans' plans with their switch times (what
`gcs.service.flown_trajectory` samples), read from the executor's plans flown
(`FlightExecutor.flown`). The REST service's vehicle host and `fleetplan fly --control`
drive their flights through it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from gcs.documents import FlightEvent
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.host.flight_handle import SNAPSHOT_HZ, FlightHandle
from gcs.flight.host.vehicle_loop import VehicleLoop
from gcs.phases import ReplanStatus
from planner import Plan

__all__ = ["ReplanHandle", "Segment"]


@dataclass(frozen=True)
class Segment:
    """One plan of a flight: flown from flight time `start` (its time 0)."""

    start: float
    plan: Plan
    replan: int | None = None
    """The replan's id; None for the mission's plan."""


class ReplanHandle(FlightHandle):
    """`FlightHandle` that also tells the plans flown; see the module."""

    @classmethod
    async def create(cls, vehicles: VehicleLoop, plan: Plan, fleet: FleetSpec,
                     options: FlightOptions | None = None, *,
                     on_event: Callable[[FlightEvent], None] | None = None,
                     snapshot_hz: float = SNAPSHOT_HZ) -> ReplanHandle:
        """`FlightHandle.create`, typed as this class."""
        handle = await super().create(vehicles, plan, fleet, options, on_event=on_event,
                                      snapshot_hz=snapshot_hz)
        assert isinstance(handle, ReplanHandle)
        return handle

    async def replanned(self) -> list[Segment]:
        """Every switched replan's plan and switch time (flight time), in order."""
        executor = self._executor

        def read() -> list[Segment]:
            switched = [r["id"] for r in executor.replans
                        if r["status"] == ReplanStatus.SWITCHED]
            later = executor.flown.segments[1:]
            return [Segment(s.start, s.plan, rid) for s, rid in zip(later, switched, strict=False)]

        return await self._vehicles.run(read)
