"""The flight as its parts see it: what pausing, fault routing, securing and the arrival at the
goals read of the flight they act on, and what they ask of it.

`FlightExecutor` (`gcs.flight.run.executor`) is the one flight; each of its parts
(`gcs.flight.run.pausing`, `gcs.flight.run.faults`, `gcs.flight.run.securing`,
`gcs.flight.run.arrival`) takes it as this protocol, so that none of them imports the executor
and each says by its use what it needs.
"""

from __future__ import annotations

from typing import Protocol

from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.setpoints import SetpointTrack
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.replan import Replanner
from gcs.flight.run.ground import GroundShow
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import FlownPlans
from gcs.flight.timeline.stream import Streamer
from gcs.phases import FlightPhase
from planner import Plan

__all__ = ["RunningFlight"]


class RunningFlight(Protocol):
    """One flight of a plan on a fleet (`FlightExecutor`)."""

    plan: Plan
    """The plan the flight started with (its scenario is the flight's)."""
    fleet: FleetSpec
    options: FlightOptions
    vehicles: list[VehicleStatus]
    context: FlightContext
    """What the procedure's steps need of the flight (`gcs.flight.procedure.context`)."""
    phase: FlightPhase
    clock: FlightClock
    flown: FlownPlans
    """The plans flown in flight time, and the motions off them (`gcs.flight.timeline.flown`)."""
    ground: GroundShow
    streamer: Streamer | None
    """The setpoint streams (None before `run` made them)."""
    tracks: list[SetpointTrack]
    """Each vehicle's plan track in force, in fleet order: the first plan's, spliced by each
    switched replan (a pause holds a vehicle only while it flies its one)."""
    replanner: Replanner | None
    """The flight's in-flight replans, once the plan is flown."""
    aborting: tuple[str, str] | None
    """The abort in force, (action, reason), or None."""

    def flight_time(self) -> float | None:
        """Seconds on the shared flight clock (None before it started)."""
        ...

    def pause(self, at: float | None = None) -> float:
        """Stop the flight clock (holding the plan at flight time `at`, or the one reached)."""
        ...

    def resume(self) -> float:
        """Restart the flight clock where `pause` stopped it."""
        ...

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        """Stop the flight: every vehicle to land or hold at once."""
        ...

    def replanner_now(self) -> Replanner:
        """The replanner, when a replan may start now; `StateConflict` otherwise."""
        ...
