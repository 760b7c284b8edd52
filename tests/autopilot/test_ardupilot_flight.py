"""Whole flights on the mock's ArduCopter personality, alone and mixed with PX4 vehicles: the
GCS detects each vehicle's autopilot and flies it by its own procedure."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from gcs.autopilot import ardupilot, px4
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.phases import EventKind
from gcs.sim import MockFleet, homes_under
from tests.flight.support import FAST_MOCK, QUICK, mock_ports, short_line, smooth_plan

pytestmark = [pytest.mark.timeout(120), pytest.mark.flight]


async def _fly(count: int, autopilots: list[str], **fleet_extra: Any
               ) -> tuple[FlightExecutor, Any, MockFleet]:
    plan = smooth_plan(short_line(count))
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, settle_time=1.0, autopilots=autopilots,
                         **mock_ports(count), **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict({**mock.fleet_dict(plan.scenario.ids), **fleet_extra})
        flight = FlightExecutor(plan, fleet, QUICK)
        try:
            outcome = await flight.start()
        except Exception as exc:
            outcome = exc
        return flight, outcome, mock


def _events(record: dict[str, Any], vehicle: str, kind: str) -> list[str]:
    return [e["detail"] for e in record["events"]
            if e.get("vehicle") == vehicle and e["kind"] == kind]


def test_an_ardupilot_fleet_flies_guided_with_takeoff() -> None:
    """Two ArduCopters: GUIDED before arming (refused while "PreArm:"), NAV_TAKEOFF, the
    plan on position targets, LAND and disarmed at their goals."""
    flight, record, mock = asyncio.run(_fly(2, ["ardupilot", "ardupilot"]))
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
