"""The fault policy: what a vehicle's fault or a separation alarm does to the flight.

``land_faulty`` lands the faulty vehicle and the others fly on (the flight then does not count
as completed); with ``landing: planned`` (the default) a faulty vehicle that still follows
setpoints (a tracking error) cannot simply descend through the others' airspace: the whole
fleet lands by a verified landing plan (`gcs.flight.landing`) instead. ``land_all`` /
``hold_all`` abort the flight (every vehicle lands / holds). Two
vehicles about to meet is nobody's single fault: a separation alarm stops everyone where they
are (PX4 Hold) rather than send anyone down through the others.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

from gcs.flight.fleetfile import FlightOptions
from gcs.flight.landing import STEERABLE_FAULTS
from gcs.flight.phases import EventKind, VehiclePhase
from gcs.flight.vehicle import Emit, VehicleStatus
from gcs.tasks import TaskSet

__all__ = ["FaultPolicy"]


class FaultPolicy:
    """Reacts to the monitor's findings (`FleetMonitor.on_fault`, `on_separation`)."""

    def __init__(self, options: FlightOptions, emit: Emit, now: Callable[[], float], *,
                 land: Callable[[VehicleStatus], Awaitable[None]],
                 abort: Callable[[str, str], Awaitable[None]],
                 aborting: Callable[[], bool]) -> None:
        self.options = options
        self.emit = emit
        self.now = now
        self.land = land
        """Sends one vehicle down (its stream stops)."""
        self.abort = abort
        """Stops the whole flight: (action land | hold, reason)."""
        self.aborting = aborting
        self.tasks = TaskSet()
        """The landings and aborts started here."""
        self.landings: list[asyncio.Future[None]] = []
        """The landings of land_faulty (a flight's end waits for their outcome)."""

    def on_fault(self, v: VehicleStatus, kind: str, detail: str) -> None:
        """Mark `v` faulty and apply the policy."""
        v.fault = kind
        v.fault_time = self.now()
        v.phase = VehiclePhase.FAULTY
        policy = self.options.policy
        self.emit(v.id, EventKind.FAULT, f"{kind}: {detail} -> policy {policy}")
        if policy == "land_faulty" and self.options.landing == "planned":
            if kind in STEERABLE_FAULTS:  # it follows setpoints: everyone lands by a plan
                self.tasks.spawn(self.abort("land", f"{v.id} {kind} ({detail}): land_faulty "
                                                    f"lands the fleet by a landing plan"))
                return
            self.emit(v.id, EventKind.LANDING_FALLBACK, f"PX4 Land: cannot be steered "
                                                        f"(fault {kind}); the others fly on")
        if policy == "land_faulty":
            self.landings.append(self.tasks.spawn(self.land(v)))
        else:
            action = "hold" if policy == "hold_all" else "land"
            self.tasks.spawn(self.abort(action, f"{v.id} {kind} ({detail})"))

    def on_separation(self, closest: float, alarm: float) -> None:
        """Two vehicles closer than `alarm`: every vehicle to Hold."""
        if self.aborting():
            return
        self.emit(None, EventKind.SEPARATION_ALARM,
                  f"vehicles {closest:.2f} m apart (alarm below {alarm:.2f} m)")
        self.tasks.spawn(self.abort("hold", f"separation {closest:.2f} m"))
