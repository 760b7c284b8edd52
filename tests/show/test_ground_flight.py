"""A show that takes off from and lands on its ground grid is flown from the ground: each
vehicle arms on its home, leaves the ground with its takeoff wave by its autopilot's way (PX4
on the plan's setpoints, ArduCopter by NAV_TAKEOFF first), keeps R apart in truth and lands on
its slot by the plan's landing wave; what cannot be flown is refused, naming the fix."""

from __future__ import annotations

import asyncio
import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs.cli.main import main
from gcs.errors import PlanRejected
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import TRACKING_TOLERANCE_M, FlightExecutor
from gcs.flight.run.ground import ground_refusal, ground_spans
from gcs.phases import EventKind
from gcs.sim import MockFleet
from gcs.wire import mavlink
from planner import Plan, Scenario, plan
from planner.methods.sequence import plan_sequence
from tests.api.support import QUICK_CROSSING
from tests.flight.flying import fly_on_mocks
from tests.flight.support import QUICK, mock_ports
from tests.sim.mavclient import MavClient
from tests.support.shows import FLEET_HOMES as HOMES
from tests.support.shows import fleet_dict, small_ground_show
from tests.support.waiting import every, until

pytestmark = pytest.mark.timeout(180)


@pytest.fixture(scope="module")
def small_show() -> Plan:
    result = plan_sequence(small_ground_show())
    assert result.ok, result.message
    return result.to_plan()


def _events(record: dict[str, Any], vehicle: str, kind: str) -> list[str]:
    return [e["detail"] for e in record["events"]
            if e.get("vehicle") == vehicle and e["kind"] == kind]


@pytest.mark.flight
def test_fly_mock_flies_it_from_the_ground(small_show: Plan, tmp_path: Path) -> None:
    path, kept = tmp_path / "show.plan.json", tmp_path / "record.json"
    path.write_text(json.dumps(small_show.to_dict()))
    assert main(["fly", str(path), "--mock", "--mock-settle", "0.5", "--quiet",
                 "--record", str(kept)]) == 0
    record = json.loads(kept.read_text())
    summary = record["summary"]
    assert summary["completed"] is True, summary["why"]
    assert summary["min_separation_measured"] >= 1.0 - TRACKING_TOLERANCE_M
    for vid in small_show.scenario.ids:
        climbs = _events(record, vid, EventKind.CLIMB)
        assert climbs == ["lifts off with its wave at t=0.0 s on the plan's setpoints"]
        assert _events(record, vid, EventKind.LANDED) == ["landed and disarmed"]
    assert not [e for e in record["events"] if e["kind"] == EventKind.AT_START]


@pytest.mark.flight
def test_px4_and_arducopter_lift_off_their_own_way_and_land_on_their_slots(
        small_show: Plan) -> None:
    samples: list[tuple[float | None, np.ndarray]] = []

    async def sample(flight: FlightExecutor, mock: MockFleet) -> None:
        sampler = asyncio.create_task(every(0.02, lambda: samples.append((
            flight.flight_time(), np.array([v.true_position_world for v in mock.vehicles])))))
        await until(lambda: flight.record is not None, "the flight's record", timeout=150.0,
                    poll=0.02)
        sampler.cancel()

    autopilots = ["px4", "ardupilot", "px4", "ardupilot"]
    flight, record, mock = asyncio.run(fly_on_mocks(small_show, QUICK, settle=1.0,
                                                    during=sample, autopilots=autopilots))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True, record["summary"]["why"]
    truth = np.array([p for _, p in samples])
    i, j = np.triu_indices(truth.shape[1], k=1)
    assert np.linalg.norm(truth[:, i] - truth[:, j], axis=2).min() >= 1.0 - TRACKING_TOLERANCE_M
    started = next(p for t, p in samples if t is not None)
    np.testing.assert_allclose(started[:, 2], 0.0, atol=0.05)  # no climb before the plan
    assert truth[:, :, 2].max() > 2.5  # and it flew the formations
    slots = small_show.scenario.assigned_goals
    for v, kind, slot, status in zip(mock.vehicles, autopilots, slots, flight.vehicles,
                                     strict=True):
        assert not v.armed
        np.testing.assert_allclose(v.true_position_world, slot, atol=0.2)
        said = [e for _, e in v.events]
        climb = _events(record, status.id, EventKind.CLIMB)
        if kind == "ardupilot":
            assert any(e.startswith("takeoff to") for e in said)
            assert not any("takeoff ended" in e for e in said)
            assert len(climb) == 1 and "(NAV_TAKEOFF to" in climb[0]
        else:
            assert not any(e.startswith("takeoff to") for e in said)
            assert climb == ["lifts off with its wave at t=0.0 s on the plan's setpoints"]


def test_a_position_target_ends_an_arducopter_takeoff_that_has_not_left_the_ground() -> None:
    """The mock as ArduCopter's GUIDED: a position target that arrives while NAV_TAKEOFF has
    not lifted it yet leaves it standing (why the GCS streams only once it is up)."""
    async def fly(target_during_takeoff: bool) -> float:
        async with MockFleet(1, settle_time=0.0, autopilots=["ardupilot"],
                             **mock_ports(1)) as mock:
            v = mock.vehicles[0]
            async with MavClient(v.gcs_address, v.listen_address, v.system_id) as c:
                c.heartbeat()
                await c.wait("HEARTBEAT", timeout=3.0, since=0.0)
                for command, params in (
                        (mavlink.MAV_CMD_DO_SET_MODE, (1.0, 4.0)),  # GUIDED
                        (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)),
                        (mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, math.nan, math.nan,
                                                        math.nan, 2.0))):
                    since = time.monotonic()
                    c.command(command, *params)
                    assert await c.ack(command, since=since) == mavlink.MAV_RESULT_ACCEPTED
                if target_during_takeoff:
                    c.send(mavlink.MAVLink_set_position_target_local_ned_message(
                        0, v.system_id, 1, mavlink.MAV_FRAME_LOCAL_NED, 0x0DF8,
                        0.0, 0.0, -2.0, 0, 0, 0, 0, 0, 0, 0, 0))
                await asyncio.sleep(1.5)
                return float(v.true_position_world[2] - v.home_world[2])

    assert asyncio.run(fly(False)) > 1.0
    assert asyncio.run(fly(True)) < 0.05


def _landing_twice(show: Plan) -> Plan:
    """`show` with its first vehicle flying its trajectory twice: down, then up again."""
    first = show.vehicles[0]
    again = dataclasses.replace(first, **{
        key: np.concatenate([getattr(first, key), getattr(first, key)[1:]])
        for key in ("position", "velocity")}, acceleration=np.concatenate(
            [first.acceleration, np.zeros((1, 3)), first.acceleration[1:]]))
    return dataclasses.replace(show, vehicles=[again, *show.vehicles[1:]])


def test_what_it_refuses_names_the_vehicle_and_the_fix(small_show: Plan) -> None:
    spans = ground_spans(small_show)
    assert isinstance(spans, dict) and set(spans) == set(small_show.scenario.ids)
    assert all(s.liftoff == 0.0 and s.touchdown is not None and s.touchdown <= small_show
               .scenario.horizon for s in spans.values())
    why = ground_refusal(_landing_twice(small_show))
    assert why is not None and "vehicle uav1 lands at t=" in why
    assert "and takes off again" in why and "two plans" in why
    fleet = FleetSpec.from_dict(fleet_dict(list(small_show.scenario.ids), HOMES[:4]))
    with pytest.raises(PlanRejected, match="starts on the ground in it, but the vehicles "
                                           "taken over are in the air"):
        FlightExecutor(small_show, fleet, take_over=True)


def _parked(show: Plan) -> Plan:
    """`show` with its first vehicle standing on its home for the whole plan."""
    first = show.vehicles[0]
    still = dataclasses.replace(
        first, position=np.repeat(first.position[:1], len(first.position), axis=0),
        velocity=np.zeros_like(first.velocity), acceleration=np.zeros_like(first.acceleration))
    return dataclasses.replace(show, vehicles=[still, *show.vehicles[1:]])


def test_a_vehicle_that_never_leaves_the_ground_is_refused_by_name(small_show: Plan) -> None:
    why = ground_refusal(_parked(small_show))
    assert why == ("refusing to fly the plan: vehicle uav1 stands on the ground for the whole "
                   "plan: leave it out of the plan (and the fleet)")


def test_fly_refuses_it_with_the_reason_and_exit_2(small_show: Plan, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The command says why before any vehicle is touched: no mock is started, and the
    user reads one error line, not a traceback."""
    path = tmp_path / "parked.plan.json"
    path.write_text(json.dumps(_parked(small_show).to_dict()))
    assert main(["fly", str(path), "--mock"]) == 2
    err = capsys.readouterr().err
    assert err == ("error: refusing to fly the plan: vehicle uav1 stands on the ground for the "
                   "whole plan: leave it out of the plan (and the fleet)\n"), err


def test_a_plan_in_the_air_has_no_ground_part() -> None:
    crossing = plan(Scenario.from_dict(QUICK_CROSSING))
    assert crossing.ok
    assert ground_spans(crossing) == {} and ground_refusal(crossing) is None
