"""Never fly without the fence asked for: the origin is asked for again (with a growing wait)
until the vehicle reports it, a failed upload is tried again, and a fleet that still has no
fence where it could have one is refused before anything arms; on a lossy mock link too."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from gcs.errors import GeofenceFailed
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.procedure import fence_upload, vehicle
from gcs.flight.procedure.context import FlightContext
from gcs.flight.run import boarding
from gcs.flight.run.boarding import fence_fleet, fence_vehicle
from gcs.geofence import build_fence, fence_items
from gcs.phases import EventKind
from gcs.sim import MockFleet
from gcs.sim.fleet import DEFAULT_WORLD_ORIGIN
from gcs.wire import mavlink
from tests.flight.fakes import FakeLink, fake_link, fake_vehicle
from tests.flight.flying import fly_on_mocks
from tests.flight.support import QUICK, short_line, smooth_plan

WORKSPACE = {"limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [20.0, 10.0, 5.0]}}
ORIGIN = tuple(DEFAULT_WORLD_ORIGIN)


class LossyOrigin(FakeLink):
    """A link that loses the vehicle's answer to the first `lost` origin requests."""

    def __init__(self, vehicle_id: str, lost: int) -> None:
        super().__init__(vehicle_id)
        self.lost = lost
        self.asked = 0

    async def request_message(self, message_id: int, timeout: float = 1.0, *,
                              clock: Any = None) -> int:
        result = await super().request_message(message_id, timeout, clock=clock)
        self.asked += 1
        if self.asked > self.lost:
            self.telemetry.gps_origin = ORIGIN
        return result


@pytest.fixture(autouse=True)
def _short_waits(monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest) -> None:
    """Short waits; off the mock, an upload that always works (the fake link has no mission
    protocol)."""
    monkeypatch.setattr(vehicle, "ORIGIN_WAIT_S", 0.01)
    monkeypatch.setattr(boarding, "fence_retry_wait", lambda _kind: 0.01)
    if request.node.get_closest_marker("flight") is None:
        async def uploaded(link: Any, items: Any) -> None:
            await asyncio.sleep(0)

        monkeypatch.setattr(boarding, "send_fence", uploaded)


def _fence(vehicles: list[Any], options: FlightOptions = QUICK) -> list[tuple[Any, str, str]]:
    events: list[tuple[Any, str, str]] = []

    async def run() -> None:
        await fence_fleet(vehicles, build_fence(WORKSPACE),
                          FlightContext(options, lambda vid, kind, detail:
                                        events.append((vid, kind, detail))), None)

    asyncio.run(run())
    return events


def _lossy(index: int, lost: int) -> Any:
    v = fake_vehicle(index, home=(1.0 + 3 * index, 1.0, 0.0))
    v.link = LossyOrigin(v.id, lost)
    return v


def test_the_origin_is_asked_for_again_until_it_comes() -> None:
    vehicles = [_lossy(0, 0), _lossy(1, vehicle.ORIGIN_TRIES - 1)]
    events = _fence(vehicles)
    assert [link.asked for link in (v.link for v in vehicles)] == [1, vehicle.ORIGIN_TRIES]
    assert [(vid, kind) for vid, kind, _ in events] == [("uav1", EventKind.GEOFENCE),
                                                        ("uav2", EventKind.GEOFENCE)]


def test_a_vehicle_whose_origin_never_came_refuses_the_flight_when_others_reported() -> None:
    vehicles = [_lossy(0, 0), _lossy(1, vehicle.ORIGIN_TRIES)]
    with pytest.raises(GeofenceFailed) as refused:
        _fence(vehicles)
    assert refused.value.vehicle == "uav2"
    assert f"no GPS_GLOBAL_ORIGIN reported after {vehicle.ORIGIN_TRIES} requests" \
        in refused.value.detail
    assert "geofence: skip" in refused.value.detail
    # the fleet file's choice to fly without a fence stands
    skipped = _fence([_lossy(0, 0), _lossy(1, 99)], QUICK.replace(geofence="skip"))
    assert [kind for _, kind, _ in skipped] == [EventKind.GEOFENCE_SKIPPED]


def test_a_fleet_without_gps_still_skips_and_says_why() -> None:
    """No vehicle reports an origin (a lab without GPS): nothing to place a fence by."""
    events = _fence([fake_vehicle(0, home=(1.0, 1.0, 0.0)), fake_vehicle(1, home=(4.0, 1.0, 0.0))])
    assert [(vid, kind) for vid, kind, _ in events] == [(None, EventKind.GEOFENCE_SKIPPED)]
    assert f"after {vehicle.ORIGIN_TRIES} requests" in events[0][2]


def test_a_refused_origin_request_is_not_asked_again() -> None:
    link = FakeLink("uav1")
    asked: list[int] = []

    async def refuse(message_id: int, timeout: float = 1.0, *, clock: Any = None) -> int:
        asked.append(message_id)
        return mavlink.MAV_RESULT_UNSUPPORTED

    link.request_message = refuse  # type: ignore[method-assign]
    assert asyncio.run(vehicle.ask_origin(link)) is False
    assert asked == [mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN]


@pytest.mark.parametrize("failures", [1, boarding.FENCE_TRANSFERS])
def test_a_failed_upload_is_tried_again_then_refused(monkeypatch: pytest.MonkeyPatch,
                                                     failures: int) -> None:
    tries: list[int] = []

    async def flaky(link: Any, items: Any) -> None:
        tries.append(len(items))
        if len(tries) <= failures:
            raise GeofenceFailed(link.vehicle_id, "upload: no answer after 5 tries of "
                                                  "MISSION_COUNT")

    monkeypatch.setattr(boarding, "send_fence", flaky)
    v = fake_vehicle(0, home=(1.0, 1.0, 0.0))
    fake_link(v).telemetry.gps_origin = ORIGIN
    events: list[tuple[Any, str, str]] = []

    def fence() -> None:
        asyncio.run(fence_vehicle(v, build_fence(WORKSPACE), None,
                                  lambda vid, kind, detail: events.append((vid, kind, detail))))

    if failures < boarding.FENCE_TRANSFERS:
        fence()
        assert [kind for _, kind, _ in events] == [EventKind.GEOFENCE_RETRY, EventKind.GEOFENCE]
        assert events[-1][2].endswith("(upload 2)")
    else:
        with pytest.raises(GeofenceFailed, match=r"uav1: geofence: upload: no answer .*"
                                                 r"\(after 3 uploads\)"):
            fence()
        assert len(tries) == boarding.FENCE_TRANSFERS


@pytest.mark.flight
@pytest.mark.timeout(150)
@pytest.mark.parametrize("seed", [1, 2])
def test_a_lossy_link_from_the_start_flies_fenced_or_not_at_all(seed: int) -> None:
    """20 % of the datagrams lost each way from the first one: every vehicle that arms has
    its fence uploaded and read back first; a flight that could not fence is refused before
    anything arms, naming why."""
    plan = smooth_plan(short_line(2))

    def lossy(mock: MockFleet) -> None:
        for v in mock.vehicles:
            v.faults.loss = 0.2

    flight, outcome, mock = asyncio.run(fly_on_mocks(
        plan, QUICK.replace(tracking_error_max=3.0, link_timeout=3.0), configure=lossy,
        seed=seed))
    assert flight.record is not None
    kinds = [(e["vehicle"], e["kind"]) for e in flight.record["events"]]
    assert (None, EventKind.GEOFENCE_SKIPPED) not in kinds
    armed = {vid for vid, kind in kinds if kind == EventKind.ARMED}
    for vid in armed:
        assert kinds.index((vid, EventKind.GEOFENCE)) < kinds.index((vid, EventKind.ARMED))
    if not armed:
        assert isinstance(outcome, Exception), outcome
        assert not any(v.armed for v in mock.vehicles)


class _LosesTheLastAck(FakeLink):
    """A vehicle's side of the mission protocol whose final MISSION_ACK is lost on the way."""

    def __init__(self) -> None:
        super().__init__("uav1")
        self.own = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.stored: list[int] = []
        self.count = 0

    def send(self, msg: Any) -> None:
        kind, fence = msg.get_type(), mavlink.MAV_MISSION_TYPE_FENCE
        if kind == "MISSION_COUNT":
            self.count = msg.count
            self._answer(self.own.mission_request_int_encode(255, 190, 0, fence))
        elif kind == "MISSION_ITEM_INT":
            if msg.seq not in self.stored:
                self.stored.append(msg.seq)
            if msg.seq + 1 < self.count:
                self._answer(self.own.mission_request_int_encode(255, 190, msg.seq + 1, fence))
            # the last: stored, and its MISSION_ACK lost

    def _answer(self, msg: Any) -> None:
        msg.pack(self.own)
        self.deliver(msg)


def test_the_last_ack_lost_is_left_to_the_read_back(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every item went and the vehicle stored them; its MISSION_ACK never came: the upload
    ends without an error, and the read-back (`send_fence`) says whether the fence is there."""
    monkeypatch.setattr(fence_upload, "ITEM_TIMEOUT_S", 0.01)
    link = _LosesTheLastAck()
    items = fence_items(build_fence(WORKSPACE), np.zeros(3), DEFAULT_WORLD_ORIGIN)
    asyncio.run(fence_upload.upload_fence(link, items))
    assert link.stored == list(range(len(items)))
