"""A silence's pause is the router's only while it lasts: heard again, the vehicle resumes the
flight from that pause, never from one an operator made since."""

from __future__ import annotations

from typing import Any

from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.procedure.context import FlightContext
from gcs.flight.run.faults import FaultRouter
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import FlownPlans
from gcs.phases import EventKind, FlightPhase
from tests.flight.fakes import fake_vehicle
from tests.flight.support import line_scenario, smooth_plan


class PausedByHand:
    """A flying flight whose pause and resume only stop and restart its clock (the streams
    are `gcs.flight.run.pausing`'s, tested with the executor)."""

    def __init__(self) -> None:
        self.plan = smooth_plan(line_scenario(2))
        self.options = FlightOptions()
        self.vehicles = [fake_vehicle(0), fake_vehicle(1)]
        self.events: list[tuple[Any, ...]] = []
        self.context = FlightContext(self.options, lambda *event: self.events.append(event))
        self.phase = FlightPhase.FLYING
        self.clock = FlightClock(10.0, 0.0, 0.0)
        self.clock.begin(0)
        self.flown = FlownPlans.of(self.plan)
        self.aborting: tuple[str, str] | None = None
        self.replanner = None
        self.streamer = None
        self.tick = 10

    def pause(self, at: float | None = None) -> float:
        self.tick += 1
        pause = self.clock.stop(self.tick)
        self.phase = FlightPhase.PAUSED
        return pause.plan_tick / 10.0

    def resume(self) -> float:
        self.tick += 1
        pause, _ = self.clock.restart(self.tick)
        self.phase = FlightPhase.FLYING
        return pause.plan_tick / 10.0


def _router() -> tuple[FaultRouter, PausedByHand]:
    flight = PausedByHand()
    return FaultRouter(flight, lambda: 0.0), flight  # type: ignore[arg-type]


def test_a_silent_vehicle_pauses_the_flight_and_resumes_it_when_heard() -> None:
    router, flight = _router()
    silent = flight.vehicles[0]
    router.on_silent(silent, 0.6)
    assert flight.phase == FlightPhase.PAUSED
    assert [e[1] for e in flight.events] == [EventKind.LINK_SILENT]
    router.on_heard(silent)
    assert flight.phase == FlightPhase.FLYING and flight.clock.pause is None


def test_heard_again_it_leaves_an_operators_pause_alone() -> None:
    """The operator resumed the silence's pause and paused again: that pause is theirs."""
    router, flight = _router()
    silent = flight.vehicles[0]
    router.on_silent(silent, 0.6)
    flight.resume()
    flight.pause()
    router.on_heard(silent)
    assert flight.phase == FlightPhase.PAUSED and flight.clock.pause is not None


def test_an_abort_under_way_is_not_resumed() -> None:
    router, flight = _router()
    silent = flight.vehicles[0]
    router.on_silent(silent, 0.6)
    flight.aborting = ("land", "operator abort")
    router.on_heard(silent)
    assert flight.clock.pause is not None


def test_a_flight_already_paused_is_not_paused_by_a_silence() -> None:
    router, flight = _router()
    flight.pause()
    router.on_silent(flight.vehicles[0], 0.6)
    router.on_heard(flight.vehicles[0])  # the operator's pause: not the router's to end
    assert flight.clock.pause is not None and flight.events == []
