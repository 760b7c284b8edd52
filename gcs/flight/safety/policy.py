"""The fault policy: what a vehicle's fault or a separation alarm does to the flight.

``land_faulty`` lands the faulty vehicle and the others fly on (the flight then does not count
as completed); with ``landing: planned`` (the default) a faulty vehicle that still follows
setpoints (a tracking error) cannot simply descend through the others' airspace: the whole
fleet lands by a verified landing plan (`gcs.flight.safety.landing`) instead. One that cannot be
steered goes straight down with PX4's Land; the others fly on only where that descent was
checked clear of their plans (`gcs.flight.safety.descent`), and otherwise land by a landing
plan that keeps clear of its descent (`landing: planned`; with `landing: px4` they hold
where they are).
``replan`` lands the faulty vehicle on its own predicted motion and replans the others
around it to their goals (`gcs.flight.replan.replan`); when no replan is flown, land_faulty's way
(PX4's Land for it, the others fly on only where its descent is clear).
``land_all`` / ``hold_all`` abort the flight (every vehicle lands / holds). Two vehicles
about to meet is nobody's single fault: a separation alarm stops everyone where they
are (PX4 Hold) rather than send anyone down through the others.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import Protocol

from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.safety.descent import DescentConflict
from gcs.flight.safety.landing import STEERABLE_FAULTS
from gcs.phases import EventKind, VehiclePhase
from gcs.tasks import TaskSet

__all__ = ["FaultPolicy", "Responder"]


class Responder(Protocol):
    """What carries out the policy's decisions on the flight (its fault routing:
    `gcs.flight.run.faults.FaultRouter`)."""

    def land(self, v: VehicleStatus) -> Awaitable[None]:
        """Sends one vehicle down (its stream stops)."""
        ...

    def abort(self, action: str, reason: str) -> Awaitable[None]:
        """Stops the whole flight: every vehicle to `action` (land | hold)."""
        ...

    def aborting(self) -> bool:
        """True once an abort is in force."""
        ...

    def descent(self, v: VehicleStatus) -> list[DescentConflict] | None:
        """The others whose plan `v`'s straight descent would come too close to
        (`gcs.flight.safety.descent`), or None when it cannot be checked."""
        ...

    def replan(self, v: VehicleStatus, kind: str) -> None:
        """Policy replan: lands `v` on its own motion and replans the others around it
        (`gcs.flight.replan.replan`), or, when they cannot be, goes land_faulty's way
        (`FaultPolicy.give_way`)."""
        ...


class FaultPolicy:
    """Decides what the monitor's findings do (`gcs.flight.safety.monitor.Watched`:
    `on_fault`, `on_separation`)."""

    def __init__(self, context: FlightContext, now: Callable[[], float],
                 responder: Responder) -> None:
        self.options = context.options
        self.emit = context.emit
        self.now = now
        self.responder = responder
        """Carries out what the policy decides (lands, aborts, replans)."""
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
        if policy == "replan":
            self.responder.replan(v, kind)
            return
        if policy == "land_faulty" and self.options.landing == "planned":
            if kind in STEERABLE_FAULTS:  # it follows setpoints: everyone lands by a plan
                self.tasks.spawn(self.responder.abort(
                    "land", f"{v.id} {kind} ({detail}): land_faulty lands the fleet by a "
                            f"landing plan"))
                return
            self.emit(v.id, EventKind.LANDING_FALLBACK, f"PX4 Land: cannot be steered "
                                                        f"(fault {kind})")
        if policy == "land_faulty":
            self.landings.append(self.tasks.spawn(self.responder.land(v)))
            self.give_way(v)
        else:
            action = "hold" if policy == "hold_all" else "land"
            self.tasks.spawn(self.responder.abort(action, f"{v.id} {kind} ({detail})"))

    def give_way(self, v: VehicleStatus) -> None:
        """`v` goes straight down: the others fly on only where its descent was checked
        clear of their plans; otherwise they land by a plan around it (or hold, `_around`)."""
        conflicts = self.responder.descent(v)
        action = "land by a plan around it" if self._around() else "hold"
        if conflicts is None:
            self.emit(v.id, EventKind.DESCENT_CONFLICT, f"descent not checked (position or "
                                                        f"flight time unknown): the others "
                                                        f"{action}")
        elif not conflicts:
            self.emit(v.id, EventKind.DESCENT_CLEAR, "straight descent clear of every other "
                                                     "vehicle's plan: the others fly on")
            return
        else:
            named = ", ".join(f"{c.vehicle} {c.distance:.2f} m at t={c.flight_time:.1f} s"
                              for c in conflicts)
            self.emit(v.id, EventKind.DESCENT_CONFLICT,
                      f"straight descent too close to {named}: the others {action}")
        if not self.responder.aborting():
            action = "land" if self._around() else "hold"
            self.tasks.spawn(self.responder.abort(action, f"{v.id} lands across the others' plans"))

    def _around(self) -> bool:
        """True when an abort with land flies a landing plan that keeps clear of a vehicle
        landing on its own (`landing: planned`); otherwise the others hold where they are."""
        return self.options.landing == "planned"

    def on_separation(self, closest: float, alarm: float, between: str = "") -> None:
        """Two vehicles (`between`, named) closer than `alarm`: every vehicle to Hold."""
        if self.responder.aborting():
            return
        named = f" ({between})" if between else ""
        self.emit(None, EventKind.SEPARATION_ALARM,
                  f"vehicles{named} {closest:.2f} m apart (alarm below {alarm:.2f} m)")
        self.tasks.spawn(self.responder.abort("hold", f"separation {closest:.2f} m"))
