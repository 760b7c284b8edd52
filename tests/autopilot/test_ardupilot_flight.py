"""Whole flights on the mock's ArduCopter personality, alone and mixed with PX4 vehicles: the
GCS detects each vehicle's autopilot and flies it by its own procedure."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from gcs.autopilot import ardupilot, px4
from gcs.errors import FlightAborted
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.run.executor import FlightExecutor
from gcs.phases import EventKind
from gcs.sim import MockFleet
from tests.flight.flying import fly_on_mocks
from tests.flight.support import QUICK, short_line, smooth_plan
from tests.support.waiting import until

pytestmark = [pytest.mark.timeout(120), pytest.mark.flight]


async def _fly(count: int, autopilots: list[str], options: FlightOptions = QUICK,
               during: Any = None, steps: int = 15, **fleet_extra: Any
               ) -> tuple[FlightExecutor, Any, MockFleet]:
    """A short line flown on `count` mock vehicles of these `autopilots`."""
    return await fly_on_mocks(smooth_plan(short_line(count, steps=steps)), options, settle=1.0,
                              during=during, fleet_extra=fleet_extra, autopilots=autopilots)


def _events(record: dict[str, Any], vehicle: str, kind: str) -> list[str]:
    return [e["detail"] for e in record["events"]
            if e.get("vehicle") == vehicle and e["kind"] == kind]


#: A flight, its record (or exception), its mocks and what was seen during its pause.
Paused = tuple[FlightExecutor, Any, MockFleet, dict[str, float]]


@pytest.fixture(scope="module")
def paused_guided() -> Paused:
    """Two ArduCopters fly a 6 s line, paused at flight time 1 s for 2.5 s (`seen`: the
    flight time of the pause and how far any vehicle moved over its last 0.5 s), then
    resumed to the end: one flight for the guided procedure's tests and the pause's."""
    seen: dict[str, float] = {}

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await until(lambda: (flight.flight_time() or 0.0) > 1.0, "flying")
        seen["t"] = flight.pause()
        await asyncio.sleep(2.0)
        before = np.stack([v.position_world for v in mock.vehicles])
        await asyncio.sleep(0.5)
        after = np.stack([v.position_world for v in mock.vehicles])
        seen["moved"] = float(np.max(np.linalg.norm(after - before, axis=1)))
        assert all(v.mode == ardupilot.GUIDED for v in mock.vehicles)
        flight.resume()

    flight, record, mock = asyncio.run(_fly(2, ["ardupilot"] * 2, during=during, steps=30))
    return flight, record, mock, seen


def test_an_ardupilot_fleet_flies_guided_with_takeoff(
        paused_guided: Paused) -> None:
    """Two ArduCopters: GUIDED before arming (refused while "PreArm:"), NAV_TAKEOFF, the
    plan on position targets, LAND and disarmed at their goals."""
    flight, record, mock, _seen = paused_guided
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    assert record["summary"]["goal_error_max"] < 0.25
    for v in mock.vehicles:
        assert v.ardupilot and not v.armed and v.mode == ardupilot.LAND
        assert any("takeoff to" in e for _, e in v.events)
        assert any(t.startswith("PreArm: ") for t in v.statustexts)  # refused while settling
    vid = flight.vehicles[0].id
    assert _events(record, vid, EventKind.MODE)[0] == "GUIDED confirmed"
    assert any("NAV_TAKEOFF" in d for d in _events(record, vid, EventKind.CLIMB))
    armed = _events(record, vid, EventKind.ARMED)[0]
    assert int(armed.split()[1]) >= 1


def test_a_mixed_fleet_flies_each_by_its_own_autopilot() -> None:
    """PX4 and ArduPilot in one flight: each is detected and flown by its own procedure."""
    flight, record, mock = asyncio.run(_fly(2, ["px4", "ardupilot"]))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    first, second = (v.id for v in flight.vehicles)
    assert _events(record, first, EventKind.MODE)[0] == px4.OFFBOARD.name + " confirmed"
    assert _events(record, second, EventKind.MODE)[0] == "GUIDED confirmed"
    assert mock.vehicles[0].mode == px4.LAND and mock.vehicles[1].mode == ardupilot.LAND
    assert [v["autopilot"] for v in record["vehicles"]] == ["px4", "ardupilot"]
    for v, goal in zip(mock.vehicles, flight.plan.scenario.goals, strict=True):
        assert np.linalg.norm(v.position_world[:2] - goal[:2]) < 0.25


def test_the_fleet_file_refuses_an_autopilot_its_heartbeat_denies() -> None:
    """A fleet file saying px4 for an ArduCopter refuses the flight, naming the fix."""
    _flight, outcome, _mock = asyncio.run(_fly(1, ["ardupilot"], autopilot="px4"))
    assert isinstance(outcome, Exception)
    assert "says ArduPilot" in str(outcome) and "fix the fleet file" in str(outcome)


def test_pause_holds_a_guided_fleet_on_one_target_then_resumes(
        paused_guided: Paused) -> None:
    """A pause holds each ArduCopter on the plan's position of that instant (one held
    position target: GUIDED keeps it), and the flight completes after the resume."""
    _flight, record, _mock, seen = paused_guided
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    assert seen["moved"] < 0.03


def test_hold_at_the_end_brakes_and_an_abort_lands() -> None:
    """at_end hold puts an ArduCopter in BRAKE (LOITER would sink without an RC throttle);
    an abort during the flight lands it (LAND) and it disarms."""
    _flight, record, mock = asyncio.run(_fly(1, ["ardupilot"], QUICK.replace(at_end="hold")))
    assert isinstance(record, dict), record
    assert mock.vehicles[0].mode == ardupilot.BRAKE and mock.vehicles[0].armed
    assert any(e["detail"] == "holding (ArduPilot BRAKE)" for e in record["events"])

    async def abort(flight: FlightExecutor, mock: MockFleet) -> None:
        await until(lambda: (flight.flight_time() or 0.0) > 0.5, "flying")
        await flight.abort("land")

    _flight, outcome, mock = asyncio.run(_fly(1, ["ardupilot"], during=abort))
    assert isinstance(outcome, FlightAborted), outcome
    assert mock.vehicles[0].mode == ardupilot.LAND and not mock.vehicles[0].armed
