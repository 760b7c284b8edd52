"""Fan-out bounds: trajectory exports at once and event streams (in total, per resource)
answer 503 with Retry-After past their limit, release their slot when they end, and an
event is serialised once for every stream that sends it."""

from __future__ import annotations

import asyncio
import csv
import io
import json
import math
import threading
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

import planner
from gcs.api.fanout import SharedJson, Slots, StreamSlots
from gcs.errors import ServiceBusy
from gcs.service import plans
from planner import Plan
from tests.api.support import example


@pytest.fixture(scope="module")
def planned(shared_client: TestClient) -> str:
    response = shared_client.post("/api/missions?wait=60", json=example("paper-circle2"))
    assert response.status_code == 201, response.text
    return response.json()["id"]


def _busy(response: Any, setting: str) -> None:
    assert response.status_code == 503, response.text
    assert int(response.headers["Retry-After"]) >= 1
    body = response.json()
    assert body["field"] == setting and setting in body["reason"]


def test_exports_past_the_limit_answer_503_and_a_finished_export_frees_its_slot(
    shared_client: TestClient, planned: str
) -> None:
    exports: Slots = shared_client.app.state.exports  # type: ignore[attr-defined]
    url = f"/api/missions/{planned}/trajectory?rate=20&format=csv"
    held = exports.held
    exports.held = exports.limit  # every slot taken by exports in progress
    try:
        _busy(shared_client.get(url), "max_concurrent_exports")
        _busy(shared_client.get(url.replace("&format=csv", "")), "max_concurrent_exports")
    finally:
        exports.held = held
    answer = shared_client.get(url)
    assert answer.status_code == 200 and answer.text.startswith("vehicle,t,")
    assert exports.held == held  # released once sent


def test_a_streamed_csv_export_is_the_whole_table(
    shared_client: TestClient, planned: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Sent in pieces of 7 rows, the rows still run 0..horizon for each vehicle in order,
    each exactly once."""
    monkeypatch.setattr(plans, "CSV_CHUNK_ROWS", 7)
    plan = shared_client.get(f"/api/missions/{planned}/plan").json()
    horizon = plan["scenario"]["dt"] * plan["scenario"]["steps"]
    exports: Slots = shared_client.app.state.exports  # type: ignore[attr-defined]
    held = exports.held
    with shared_client.stream(
            "GET", f"/api/missions/{planned}/trajectory?rate=100&format=csv") as response:
        assert response.status_code == 200
        pieces = response.iter_text()
        text = next(pieces)
        assert exports.held == held + 1  # its slot is held while rows are still being sent
        text += "".join(pieces)
    assert exports.held == held
    rows = list(csv.DictReader(io.StringIO(text)))
    per_vehicle = math.floor(horizon * 100 + 1e-9) + 1
    assert per_vehicle > 7
    ids = [v["id"] for v in plan["scenario"]["vehicles"]]
    assert [r["vehicle"] for r in rows] == [i for i in ids for _ in range(per_vehicle)]
    for vehicle in ids:
        times = [float(r["t"]) for r in rows if r["vehicle"] == vehicle]
        assert times == sorted(times) and times[0] == 0.0
        assert times[-1] == pytest.approx(horizon, abs=1e-6)


def test_a_streamed_json_export_is_the_plan_sampled_one_vehicle_at_a_time(
    shared_client: TestClient, planned: str
) -> None:
    """Sent in one piece per vehicle (after the times), the document is the TrajectoryOut
    the plan's own sampling gives, strict JSON, and holds its slot until it is sent."""
    plan = Plan.from_dict(shared_client.get(f"/api/missions/{planned}/plan").json())
    exports: Slots = shared_client.app.state.exports  # type: ignore[attr-defined]
    held = exports.held
    with shared_client.stream("GET", f"/api/missions/{planned}/trajectory?rate=50"
                              ) as response:
        assert response.status_code == 200
        assert response.headers["content-type"].startswith("application/json")
        pieces = response.iter_raw()
        body = next(pieces)
        assert exports.held == held + 1  # its slot is held while vehicles are still sent
        body += b"".join(pieces)
    assert exports.held == held
    assert b"NaN" not in body and b"Infinity" not in body  # strict JSON
    document = json.loads(body)
    times = np.asarray(document["t"])
    expected = plan.sample(times)
    assert document["mission_id"] == planned and document["rate"] == 50.0
    assert document["frame"] == "world_enu"
    assert times[0] == 0.0 and times[-1] == pytest.approx(plan.scenario.horizon, abs=1e-9)
    assert [v["id"] for v in document["vehicles"]] == list(plan.scenario.ids)
    for i, vehicle in enumerate(document["vehicles"]):
        for key, want in (("position", expected.position), ("velocity", expected.velocity),
                          ("acceleration", expected.acceleration)):
            np.testing.assert_allclose(np.asarray(vehicle[key]), want[i], atol=1e-12)


def test_a_json_export_never_holds_more_than_one_vehicle_at_once() -> None:
    """40 concurrent JSON exports of a long mission once held 40 whole documents (3.7 GB):
    the document is made one vehicle at a time, so no piece is much more than one
    vehicle's share of it, and the pieces join into the whole strict-JSON document."""
    plan = planner.plan(example("paper-circle8"))
    vehicles = len(plan.vehicles)
    pieces = list(plans.trajectory_json_chunks("m", plan, 100.0, 10**7))
    whole = b"".join(pieces)
    assert len(pieces) == vehicles + 2  # the times, each vehicle, the closing brackets
    assert max(len(p) for p in pieces) < 1.5 * len(whole) / vehicles
    document = json.loads(whole)
    assert [v["id"] for v in document["vehicles"]] == list(plan.scenario.ids)


def test_event_streams_are_bounded_per_resource_and_in_total(
    shared_client: TestClient, planned: str
) -> None:
    streams: StreamSlots = shared_client.app.state.streams  # type: ignore[attr-defined]
    path = f"/api/missions/{planned}/events"
    streams.open[path] = streams.per_resource
    try:
        _busy(shared_client.get(path), "max_event_streams_per_resource")
    finally:
        del streams.open[path]
    streams.open["/api/elsewhere"] = streams.total
    try:
        _busy(shared_client.get(path), "max_event_streams")
    finally:
        del streams.open["/api/elsewhere"]
    with shared_client.stream("GET", path) as response:  # a planned mission: `done`, then end
        assert response.status_code == 200
        assert "event: done" in "".join(response.iter_text())
    assert streams.open == {}  # released when the stream ended


def test_slots_are_counted_across_threads() -> None:
    slots = Slots(3, "max_concurrent_exports", "exports")
    entered, release = threading.Barrier(4), threading.Event()
    refused: list[ServiceBusy] = []

    def hold() -> None:
        with slots.hold():
            entered.wait(10)
            release.wait(10)

    threads = [threading.Thread(target=hold) for _ in range(3)]
    for thread in threads:
        thread.start()
    entered.wait(10)
    try:
        with slots.hold():
            pass
    except ServiceBusy as exc:
        refused.append(exc)
    release.set()
    for thread in threads:
        thread.join(10)
    assert len(refused) == 1 and refused[0].retry_after_s > 0
    assert slots.held == 0
    with slots.hold():
        assert slots.held == 1


def test_an_event_published_to_many_streams_is_serialised_once(
    monkeypatch: pytest.MonkeyPatch
) -> None:
    """A broadcast hands every follower the same object, so 50 streams of one flight cost
    one serialisation per event, not 50."""
    from gcs.api import fanout
    from gcs.service.events import Broadcast

    dumps = []
    real = fanout.json.dumps
    monkeypatch.setattr(fanout.json, "dumps", lambda *a, **k: dumps.append(1) or real(*a, **k))
    shared, broadcast = SharedJson(), Broadcast()

    async def main() -> list[list[str]]:
        async def follow() -> list[str]:
            return [shared.text(data) async for _, data in broadcast.follow([], None)]

        followers = [asyncio.ensure_future(follow()) for _ in range(50)]
        await asyncio.sleep(0)  # every follower subscribed
        broadcast.publish("event", {"t": 1.0, "kind": "flight_start"})
        broadcast.publish("done", {"status": "completed"})
        return await asyncio.gather(*followers)

    texts = asyncio.run(main())
    assert all(t == ['{"t": 1.0, "kind": "flight_start"}', '{"status": "completed"}']
               for t in texts)
    assert len(dumps) == 2


def test_one_serialisation_per_event_object_and_never_nan() -> None:
    shared = SharedJson(size=2)
    event = {"t": 1.5, "x": float("nan"), "v": [1.0, float("inf")]}
    text = shared.text(event)
    assert text == '{"t": 1.5, "x": null, "v": [1.0, null]}'
    assert shared.text(event) is text  # the same object: computed once
    assert shared.text(dict(event)) == text  # an equal object: the same text
    for n in range(5):  # bounded: old entries go, and a new object never gets a stale text
        assert shared.text({"n": n}) == f'{{"n": {n}}}'


def test_a_follower_that_stops_reading_is_ended_not_buffered_without_bound() -> None:
    """A client that stops reading its event stream is ended once it falls MAX_BACKLOG
    events behind; a reading follower of the same broadcast gets every event."""
    from gcs.service.events import MAX_BACKLOG, Broadcast

    broadcast = Broadcast()
    published = range(1, MAX_BACKLOG + 50)

    async def main() -> tuple[list[int], list[int], int]:
        stalled = broadcast.follow([("event", {"n": 0})], None)
        first = await anext(stalled)  # subscribed (its history taken), then it stops reading
        got: list[int] = []

        async def read() -> None:
            async for kind, data in broadcast.follow([], None):
                if kind == "done":
                    return
                got.append(data["n"])

        reading = asyncio.ensure_future(read())
        await asyncio.sleep(0)
        for n in published:
            broadcast.publish("event", {"n": n})
            if n % 100 == 0:
                await asyncio.sleep(0)  # the reader keeps up
        during = broadcast.listening
        broadcast.publish("done", {})
        await reading
        rest = [data["n"] async for _, data in stalled]
        return [first[1]["n"], *rest], got, during

    stalled, read, listening = asyncio.run(main())
    assert read == list(published)
    assert listening == 2
    # the stalled one got its history, then was ended: nothing kept for it past the bound
    assert stalled == [0]
    assert broadcast.listening == 0
