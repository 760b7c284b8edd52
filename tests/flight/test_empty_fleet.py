"""Every path that can meet an empty fleet (no vehicle left, or none at all) ends cleanly."""

from __future__ import annotations

import asyncio
import math
import time

import pytest

from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.station import StationStalls
from gcs.flight.procedure import endings, vehicle
from gcs.flight.procedure.context import FlightContext
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.run.record import FlightRecorder
from gcs.flight.run.summary import summarise
from gcs.flight.timeline.stream import Streamer
from gcs.phases import EventKind, VehiclePhase
from gcs.tasks import all_or_first_error
from tests.flight.fakes import fake_link, fake_vehicle
from tests.flight.flying import monitor_of
from tests.flight.support import line_scenario, smooth_plan

pytestmark = pytest.mark.timeout(60)

OPTIONS = FlightOptions()


def _events() -> tuple[list[tuple[str | None, str, str]], vehicle.Emit]:
    events: list[tuple[str | None, str, str]] = []
    return events, lambda vid, kind, detail: events.append((vid, kind, detail))


def test_all_of_nothing_returns() -> None:
    asyncio.run(all_or_first_error([]))
    asyncio.run(all_or_first_error(iter(())))


def test_all_still_raises_the_first_error() -> None:
    async def fail() -> None:
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        asyncio.run(all_or_first_error([fail(), asyncio.sleep(5)]))


def test_wait_disarmed_of_nobody_returns_at_once() -> None:
    events, emit = _events()
    asyncio.run(asyncio.wait_for(endings.wait_disarmed([], FlightContext(OPTIONS, emit)),
                                 1.0))  # bound
    assert events == []


def test_secure_without_a_link_does_nothing() -> None:
    v = fake_vehicle(0)
    v.link = None
    events, emit = _events()
    asyncio.run(endings.secure(v, "land", FlightContext(OPTIONS, emit)))
    assert events == [] and v.phase == VehiclePhase.PENDING


@pytest.mark.parametrize("count", [0, 1])
def test_monitor_with_no_or_one_vehicle_measures_no_separation(count: int) -> None:
    vehicles = [fake_vehicle(i) for i in range(count)]
    for v in vehicles:
        v.phase = VehiclePhase.FLYING
    faults: list[tuple[str, str, float]] = []
    monitor = monitor_of(vehicles, faults, StationStalls())
    monitor.check(time.monotonic())
    assert faults == [] and math.isinf(monitor.min_separation)


def test_summary_of_no_vehicle_is_not_complete() -> None:
    plan = smooth_plan(line_scenario(1))
    summary = summarise(FlightRecorder([], []), plan, OPTIONS, [], flight_start=0.0,
                        now=10.0, missed_ticks=0, lateness=[], error=None)
    assert summary["completed"] is False
    assert summary["goal_error_max"] is None and summary["faults"] == {}


def _executor(count: int, **options: object) -> FlightExecutor:
    plan = smooth_plan(line_scenario(count))
    fleet = FleetSpec.from_dict({"vehicles": [
        {"id": f"uav{i + 1}", "connection": f"udpin:127.0.0.1:{30000 + i}",
         "system_id": i + 1, "home": [3.0 * i + 1.0, 1.0, 0.0]} for i in range(count)]})
    ex = FlightExecutor(plan, fleet, FlightOptions(**options))  # type: ignore[arg-type]
    ex.streamer = Streamer(ex.options.rate_hz)
    for i, v in enumerate(ex.vehicles):
        fake = fake_vehicle(i, home=tuple(v.spec.home))  # type: ignore[arg-type]
        v.link, v.home = fake.link, fake.home
    return ex


@pytest.mark.parametrize("at_end", ["land", "hold"])
def test_finish_with_no_live_vehicle(at_end: str) -> None:
    """land_faulty took every vehicle down: the end of the flight has nobody to land or
    hold, and waits only for the ones already landing."""
    ex = _executor(2, at_end=at_end, policy="land_faulty")
    for v in ex.vehicles:
        v.fault, v.phase = "estimate_invalid", VehiclePhase.LANDING
        v.linked.telemetry.armed = False
    asyncio.run(asyncio.wait_for(ex.finish(), 5.0))  # bound
    assert [v.phase for v in ex.vehicles] == [VehiclePhase.LANDED] * 2
    kinds = [e["kind"] for e in ex.recorder.events]
    assert kinds == [EventKind.LANDED, EventKind.LANDED]
    assert not [c for v in ex.vehicles for c in fake_link(v).commands]


def test_abort_with_every_vehicle_already_down_sends_nothing() -> None:
    ex = _executor(2)
    for v in ex.vehicles:
        v.phase = VehiclePhase.STOPPED
    asyncio.run(asyncio.wait_for(ex.abort("land", "test"), 5.0))  # bound
    assert [v.phase for v in ex.vehicles] == [VehiclePhase.STOPPED] * 2
    assert not [c for v in ex.vehicles for c in fake_link(v).commands]


def test_record_of_a_flight_that_never_streamed() -> None:
    ex = _executor(1)
    ex.streamer = None
    ex.close_record(None)
    assert ex.record is not None
    assert ex.record["summary"]["completed"] is False
    assert ex.snapshot()["vehicles"][0]["id"] == "uav1"
