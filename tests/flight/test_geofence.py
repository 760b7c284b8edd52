"""The geofence: built from the scenario, placed on the Earth per vehicle, uploaded to and
read back from the mock by the mission protocol, and a breach seen as a fault."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from gcs import frames
from gcs.autopilot import px4
from gcs.errors import GeofenceFailed
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.procedure import vehicle as vehicle_module
from gcs.flight.procedure.context import FlightContext
from gcs.flight.run import executor as executor_module
from gcs.flight.run.boarding import fence_fleet, fence_vehicle
from gcs.flight.run.executor import FlightExecutor
from gcs.geofence import FenceItem, build_fence, fence_items, item_mismatch
from gcs.phases import EventKind
from gcs.sim import MockFleet
from gcs.sim.fleet import DEFAULT_WORLD_ORIGIN
from gcs.wire import mavlink
from tests.flight.fakes import fake_link, fake_vehicle
from tests.flight.flying import fly_on_mocks
from tests.flight.support import QUICK, short_line, smooth_plan
from tests.support.waiting import ENDED, until

_m = mavlink
WORKSPACE = {"limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [20.0, 10.0, 5.0]}}
OBSTACLES = [
    {"id": "pillar", "cylinder": {"center": [15.0, 6.0], "radius": 0.5, "z": [0.0, 5.0]}},
    {"id": "shelf", "box": {"min": [12.0, 1.0, 0.0], "max": [14.0, 2.0, 2.0]}},
    {"id": "hut", "prism": {"polygon": [[16.0, 1.0], [18.0, 1.0], [17.0, 3.0]], "z": [0.02, 3]}},
    {"id": "net", "box": {"min": [12.0, 7.0, 2.5], "max": [14.0, 9.0, 2.6]}},
]


def test_the_fence_is_the_workspace_rectangle_and_the_obstacles_standing_on_the_ground() -> None:
    fence = build_fence({**WORKSPACE, "obstacles": OBSTACLES})
    assert [(s.source, s.inclusion, s.radius) for s in fence.shapes] == [
        ("workspace", True, None), ("pillar", False, 0.5), ("shelf", False, None),
        ("hut", False, None)]
    assert fence.shapes[0].points.tolist() == [[0, 0], [20, 0], [20, 10], [0, 10]]
    assert fence.shapes[2].points.tolist() == [[12, 1], [14, 1], [14, 2], [12, 2]]
    assert fence.not_fenced == ("net",)  # 2.5 m up: PX4 cannot fence the air above only
    assert fence.breaches([5.0, 5.0]) == []
    assert fence.breaches([15.2, 6.0]) == ["pillar"]
    assert fence.breaches([17.0, 1.5]) == ["hut"]
    assert fence.breaches([-0.1, 5.0]) == ["workspace"]
    # without the key (a scenario before obstacles) only the workspace is fenced
    assert [s.source for s in build_fence(WORKSPACE).shapes] == ["workspace"]


def test_fence_items_are_each_vehicles_own_latitude_and_longitude() -> None:
    """A vehicle's items, placed from its own origin (its home on the Earth), come back to the
    world points; from the world origin, 10 m north is 10 / 111 195 degrees of latitude."""
    fence = build_fence({**WORKSPACE, "obstacles": OBSTACLES})
    origin = DEFAULT_WORLD_ORIGIN
    from_world = fence_items(fence, np.zeros(3), origin)
    assert [i.command for i in from_world] == [_m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 4 \
        + [_m.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION] \
        + [_m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION] * 7
    assert [i.param1 for i in from_world] == [4.0] * 4 + [0.5] + [4.0] * 4 + [3.0] * 3
    assert from_world[0].x == round(origin.lat * 1e7)
    assert from_world[2].x - from_world[0].x == pytest.approx(10.0 / 111_250 * 1e7, rel=3e-3)
    home = np.array([7.0, 3.0, 0.0])
    own = frames.enu_to_geodetic(home, origin)
    items = fence_items(fence, home, own)
    for mine, theirs in zip(items, from_world, strict=True):  # the same places on the Earth
        assert abs(mine.x - theirs.x) <= 1 and abs(mine.y - theirs.y) <= 1
    back = frames.geodetic_to_enu(frames.Geodetic(items[2].x * 1e-7, items[2].y * 1e-7,
                                                  own.alt), own)
    assert back[:2] + home[:2] == pytest.approx([20.0, 10.0], abs=0.02)  # 1e-7 deg is ~1 cm


def test_a_fence_read_back_is_compared_item_by_item() -> None:
    sent = [FenceItem(5001, 4.0, 473977420, 85455940), FenceItem(5004, 0.5, 1, 2)]
    assert item_mismatch(sent, [FenceItem(5001, 4.0, 473977421, 85455940),
                                FenceItem(5004, 0.50000001, 1, 2)]) is None
    assert "read back 1 items, sent 2" in item_mismatch(sent, sent[:1])
    assert "item 1" in item_mismatch(sent, [sent[0], FenceItem(5004, 0.5, 1, 9)])
    assert "item 0" in item_mismatch(sent, [FenceItem(5002, 4.0, 473977420, 85455940),
                                            sent[1]])


def _fence_fleet(vehicles: list, options: FlightOptions,
                 origin: frames.Geodetic | None) -> list[tuple[Any, str, str]]:
    events: list[tuple[Any, str, str]] = []

    async def run() -> None:
        await fence_fleet(vehicles, build_fence(WORKSPACE),
                          FlightContext(options, lambda vid, kind, detail:
                                        events.append((vid, kind, detail))), origin)

    asyncio.run(run())
    return events


def test_without_an_origin_the_default_skips_and_says_why_and_an_explicit_upload_refuses(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(vehicle_module, "ORIGIN_WAIT_S", 0.01)  # asked again with a growing wait
    vehicles = [fake_vehicle(0, home=(1.0, 1.0, 0.0)), fake_vehicle(1, home=(4.0, 1.0, 0.0))]
    events = _fence_fleet(vehicles, FlightOptions(), None)
    assert [(vid, kind) for vid, kind, _ in events] == [(None, EventKind.GEOFENCE_SKIPPED)]
    assert "no geodetic origin for uav1, uav2" in events[0][2]
    with pytest.raises(GeofenceFailed, match=r"uav1: geofence: .*upload asked"):
        _fence_fleet(vehicles, FlightOptions(geofence="upload"), None)
    skipped = _fence_fleet(vehicles, FlightOptions(geofence="skip"), DEFAULT_WORLD_ORIGIN)
    assert skipped == [(None, EventKind.GEOFENCE_SKIPPED, "fleet option geofence: skip")]


def test_a_home_outside_the_fence_refuses_the_vehicle() -> None:
    v = fake_vehicle(0, home=(25.0, 1.0, 0.0))
    fake_link(v).telemetry.gps_origin = tuple(DEFAULT_WORLD_ORIGIN)
    with pytest.raises(GeofenceFailed, match=r"uav1: .*home \[25.0, 1.0, 0.0\] lies outside"):
        asyncio.run(fence_vehicle(v, build_fence(WORKSPACE), None, lambda *a: None))


def test_the_option_is_validated() -> None:
    assert FlightOptions.from_dict({"geofence": "skip"}).geofence == "skip"
    with pytest.raises(Exception, match=r"flight\.geofence: must be one of upload, skip"):
        FlightOptions.from_dict({"geofence": "maybe"})


# ------------------------------------------------------------------ on the mock, over UDP

async def _fly(plan: Any, options: FlightOptions, obstacles: list[dict[str, Any]],
               monkeypatch: pytest.MonkeyPatch, push: tuple[float, float, float] | None = None
               ) -> tuple[FlightExecutor, Any, MockFleet]:
    """Fly `plan` on mocks (`tests.flight.flying.fly_on_mocks`) with `obstacles` in the
    scenario the fence is built from; `push` offsets vehicle 2's setpoints (LOCAL_NED) once
    the flight clock runs."""
    monkeypatch.setattr(executor_module, "build_fence",
                        lambda scenario: build_fence({**scenario, "obstacles": obstacles}))

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        if push is None:
            return
        # a flight that ended early never gets there
        await until(lambda: flight.phase in ENDED or (flight.flight_time() or -1.0) >= 0.5,
                    "flight time 0.5 s or the flight's end", timeout=60.0, poll=0.02)
        if (flight.flight_time() or -1.0) >= 0.5:
            mock.vehicles[1].faults.offset_ned = push

    return await fly_on_mocks(plan, options, during=during)


@pytest.mark.flight
def test_the_fence_round_trips_on_the_mock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every mock holds the fence, as the mission protocol stored it, in its own frame: its
    breach check finds the pillar where the world frame has it; the floating net is named."""
    plan = smooth_plan(short_line(2))
    obstacles = [{"id": "pillar", "cylinder": {"center": [5.5, 3.0], "radius": 0.4,
                                               "z": [0.0, 5.0]}},
                 {"id": "net", "box": {"min": [2.0, 2.0, 3.0], "max": [3.0, 3.0, 3.2]}}]
    _flight, record, mock = asyncio.run(_fly(plan, QUICK, obstacles, monkeypatch))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True
    kinds = [(e["vehicle"], e["kind"]) for e in record["events"]]
    assert kinds.index(("uav1", EventKind.GEOFENCE)) < kinds.index(("uav1", EventKind.ARMED))
    assert ("uav2", EventKind.GEOFENCE) in kinds
    not_fenced = [e for e in record["events"] if e["kind"] == EventKind.GEOFENCE_NOT_FENCED]
    assert len(not_fenced) == 1 and not_fenced[0]["detail"].endswith(": net")
    pillar = np.array([5.5, 3.0, 1.0])
    for vehicle in mock.vehicles:
        stored = vehicle.missions.items[_m.MAV_MISSION_TYPE_FENCE]
        assert [i.command for i in stored] == [5001] * 4 + [5004]
        assert all(i.frame == _m.MAV_FRAME_GLOBAL for i in stored)
        local = frames.world_to_ned(pillar, vehicle.home_world)
        fence = vehicle.geofence
        assert not fence.inside(local, 0, 0)  # in the pillar
        assert fence.inside(local + np.array([0.5, 0.0, 0.0]), 0, 0)  # 0.5 m north of its centre
        outside = frames.world_to_ned([-0.2, 1.0, 1.0], vehicle.home_world)
        assert not fence.inside(outside, 0, 0)  # west of the workspace


@pytest.mark.flight
def test_a_fence_the_vehicle_refuses_refuses_the_flight_before_arming(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A circle of radius 0 is refused by PX4's mission manager (MAV_MISSION_INVALID_PARAM1):
    the flight ends naming the vehicle, and nothing was armed."""
    plan = smooth_plan(short_line(2))
    bad = [{"id": "dot", "cylinder": {"center": [5.5, 3.0], "radius": 0.0, "z": [0.0, 5.0]}}]
    flight, outcome, mock = asyncio.run(_fly(plan, QUICK, bad, monkeypatch))
    assert isinstance(outcome, GeofenceFailed), outcome
    assert outcome.vehicle in ("uav1", "uav2")
    assert "MAV_MISSION_INVALID_PARAM1" in str(outcome)
    assert flight.record is not None
    assert EventKind.ARMED not in [e["kind"] for e in flight.record["events"]]
    assert not any(v.armed for v in mock.vehicles)


@pytest.mark.flight
def test_a_vehicle_pushed_out_of_its_fence_holds_and_is_a_geofence_breach_fault(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """uav2 pushed 6 m east (out of the workspace's x <= 8, away from uav1): PX4's GF_ACTION 2
    puts it in Hold, and the station records a geofence_breach fault (not a left_offboard
    one)."""
    plan = smooth_plan(short_line(2))
    options = QUICK.replace(tracking_error_max=10.0, policy="land_faulty")
    flight, record, mock = asyncio.run(_fly(plan, options, [], monkeypatch,
                                            push=(0.0, 6.0, 0.0)))
    if not isinstance(record, dict):
        assert flight.record is not None, record
        record = flight.record
    assert record["summary"]["faults"] == {"uav2": "geofence_breach"}
    faults = [e for e in record["events"] if e["kind"] == EventKind.FAULT]
    assert faults[0]["vehicle"] == "uav2"
    assert faults[0]["detail"].startswith("geofence_breach: ")
    # the mock's own log: PX4's GF_ACTION put it in Hold (the GCS may land it before a
    # HEARTBEAT shows the Hold)
    happened = [what for _t, what in mock.vehicles[1].events]
    breach = happened.index("geofence breached (GF_ACTION 2)")
    assert f"mode {px4.OFFBOARD.name} -> {px4.HOLD.name}" in happened[breach:]
    said = [e["detail"] for e in record["events"]
            if e["kind"] == EventKind.STATUSTEXT and e["vehicle"] == "uav2"]
    assert "Approaching on Geofence" in said
    assert not any(e["kind"] == EventKind.FAULT and e["vehicle"] == "uav1"
                   for e in record["events"])


def test_a_planned_scenarios_obstacles_become_its_fence() -> None:
    """The window example as the planner echoes it (`Scenario.to_dict`): the walls standing
    on the ground are exclusions, the wall above the window is named as not fenceable."""
    from planner import Scenario
    from tests.planner.conftest import load_example

    fence = build_fence(Scenario.from_dict(load_example("window8")).to_dict())
    assert [(s.source, s.inclusion) for s in fence.shapes] == [
        ("workspace", True), ("wall-left", False), ("wall-right", False),
        ("wall-below", False)]
    assert fence.not_fenced == ("wall-above",)
