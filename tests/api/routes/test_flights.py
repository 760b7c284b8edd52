"""Flights through the API on in-process mock PX4 vehicles (real MAVLink over UDP loopback):
fly to completion, abort, live state, every refusal, and what survives a restart."""

from __future__ import annotations

import copy
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.fleet.fleetfile import MAX_RATE_HZ, MIN_RATE_HZ
from gcs.service.settings import Settings
from gcs.service.store import Store
from tests.api.support import (
    QUICK,
    QUICK_CROSSING,
    SHORT_CROSSING,
    example,
    plan_mission,
    sse_events,
)
from tests.support.waiting import wait_for


def heard(client: TestClient) -> list[dict[str, Any]] | None:
    """Every vehicle's monitor state once each HEARTBEAT is fresh, else None."""
    vehicles: list[dict[str, Any]] = client.get("/api/vehicles").json()["vehicles"]
    fresh = all(v["heartbeat_age"] is not None and v["heartbeat_age"] < 2 for v in vehicles)
    return vehicles if fresh else None


@dataclass
class Flown:
    """One flight flown to completion on a fresh service, and what the API said around it."""

    settings: Settings
    idle: dict[str, Any]
    idle_vehicles: list[dict[str, Any]]
    mission: dict[str, Any]
    created: dict[str, Any]
    events: list[tuple[str, dict[str, Any]]]
    stored: dict[str, Any]
    record: dict[str, Any]
    listed: list[dict[str, Any]]
    active: list[dict[str, Any]]
    after: dict[str, Any]
    after_vehicles: list[dict[str, Any]]


@pytest.fixture(scope="module")
def flown(module_mock_settings: Settings) -> Flown:
    """QUICK_CROSSING flown once (the tests below read it; the restart test reopens its
    database)."""
    with TestClient(create_app(module_mock_settings)) as client:
        idle = client.get("/api/vehicles").json()
        idle_vehicles = wait_for(lambda: heard(client), "the mock vehicles' heartbeats", 10)
        mission = plan_mission(client, QUICK_CROSSING)
        response = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK)
        assert response.status_code == 201, response.text
        created = response.json()
        events = sse_events(client, created["links"]["events"])
        stored = client.get(created["links"]["self"]).json()
        record = client.get(created["links"]["record"])
        assert record.status_code == 200
        listed = client.get(f"/api/missions/{mission['id']}/flights").json()
        active = client.get("/api/flights?active=true").json()["flights"]
        after = client.get("/api/vehicles").json()
        after_vehicles = wait_for(lambda: heard(client),
                                  "the monitor to hear the vehicles again", 10)
    return Flown(module_mock_settings, idle, idle_vehicles, mission, created, events, stored,
                 json.loads(record.text), listed, active, after, after_vehicles)


@pytest.mark.flight
def test_fly_to_completion_with_live_state_and_a_record(flown: Flown) -> None:
    assert flown.idle["fleet"] == {"kind": "mock", "vehicles": 4, "flying": None,
                                   "ids": ["uav1", "uav2", "uav3", "uav4"],
                                   "world_origin": {"lat": 47.397742, "lon": 8.545594,
                                                    "alt": 488.0},
                                   "grows_to": 256, "vehicle_process": "running"}
    for v in flown.idle_vehicles:
        assert v["link"] == "monitor" and v["armed"] is False and v["mode"]
        np.testing.assert_allclose(v["position"], v["home"], atol=0.05)

    mission, flight, events = flown.mission, flown.created, flown.events
    assert flight["status"] == "starting" and flight["mission_id"] == mission["id"]
    kinds = [kind for kind, _ in events]
    assert kinds[0] == "status" and kinds[-1] == "done"
    statuses = [data["status"] for kind, data in events if kind == "status"]
    assert "running" in statuses
    # running from the first telemetry that says flying: never while connecting or climbing
    running = [data.get("status") for _, data in events].index("running")
    before = [d["phase"] for k, d in events[:running] if k == "telemetry"]
    after = [d["phase"] for k, d in events[running:] if k == "telemetry"]
    assert set(before) <= {"created", "connecting", "preparing", "gathering"}
    assert after and after[0] in ("flying", "finishing")
    telemetry = [data for kind, data in events if kind == "telemetry"]
    flying = [t for t in telemetry if t["phase"] == "flying"]
    assert flying, "no telemetry while the flight clock ran"
    assert {v["id"] for v in flying[-1]["vehicles"]} == {"a", "b", "c", "d"}
    assert all(v["mode"] == "OFFBOARD" and v["armed"] for v in flying[-1]["vehicles"])
    logged = [data["kind"] for kind, data in events if kind == "event"]
    assert "flight_start" in logged and "landed" in logged

    done = events[-1][1]
    assert done["status"] == "completed", done
    summary = done["summary"]
    assert summary["completed"] is True
    assert summary["goal_error_max"] < 0.2
    assert summary["min_separation_measured"] > 1.0 - 0.1
    # Setpoints streamed all through (rate figures: bench/stream.py, bench/service.py).
    assert summary["setpoint_rate_hz"] > 10.0  # bound

    stored = flown.stored
    assert stored["status"] == "completed" and stored["has_record"]
    assert stored["summary"] == summary and stored["live"] is None
    assert [e["kind"] for e in stored["events"]] == logged
    assert flown.record["summary"] == summary
    # the request's options are the ones flown (the rest are the fleet's)
    assert {k: flown.record["options"][k] for k in QUICK} == QUICK
    assert [e["id"] for e in flown.listed] == [flight["id"]]
    assert flown.active == []

    # Back to the monitor: the vehicles are landed, disarmed, at their goals.
    assert flown.after["fleet"]["flying"] is None
    by_id = {v["id"]: v for v in flown.after_vehicles}
    for planned in QUICK_CROSSING["vehicles"]:
        v = by_id[planned["id"]]
        assert v["armed"] is False
        np.testing.assert_allclose(v["position"][:2], planned["goal"][:2], atol=0.2)
        assert v["position"][2] < 0.1


@pytest.mark.flight
def test_the_last_telemetry_before_done_shows_the_fleet_landed_and_disarmed(
        flown: Flown) -> None:
    """A flight's stream ends with the fleet as it is: the last telemetry before `done` shows
    every vehicle landed and disarmed, so a page following the stream never keeps a vehicle
    "armed / landing" after it disarmed."""
    events = flown.events
    kinds = [kind for kind, _ in events]
    assert kinds[-1] == "done" and events[-1][1]["status"] == "completed", events[-1]
    landed = {data["vehicle"] for kind, data in events
              if kind == "event" and data.get("kind") == "landed"}
    assert landed == {v["id"] for v in QUICK_CROSSING["vehicles"]}
    last = max(i for i, kind in enumerate(kinds) if kind == "telemetry")
    # no event after the last telemetry leaves the page's table behind it
    assert "event" not in kinds[last:], kinds[last:]
    final = events[last][1]
    assert [(v["id"], v["armed"], v["phase"]) for v in final["vehicles"]] == [
        (v["id"], False, "landed") for v in QUICK_CROSSING["vehicles"]]


@pytest.mark.flight
def test_abort_lands_everyone_at_once(mock_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, SHORT_CROSSING)
        flight = client.post(f"/api/missions/{mission['id']}/flights").json()
        url = flight["links"]["self"]
        wait_for(lambda: (client.get(url).json()["live"] or {}).get("phase") == "flying",
                 "the flight clock", 30)
        while_flying = client.get("/api/vehicles").json()
        assert while_flying["fleet"]["flying"] == flight["id"]
        assert all(v["link"] == "flight" and v["armed"] for v in while_flying["vehicles"])
        # One flight at a time, and no deleting a mission in the air.
        again = client.post(f"/api/missions/{mission['id']}/flights")
        assert again.status_code == 409 and again.json()["field"] == "fleet"
        assert "is flying" in again.json()["reason"]
        assert client.delete(f"/api/missions/{mission['id']}").status_code == 409

        response = client.post(flight["links"]["abort"], json={"action": "land"})
        assert response.status_code == 202
        assert response.json()["status"] == "aborting"
        done = sse_events(client, flight["links"]["events"])[-1]
        assert done[0] == "done" and done[1]["status"] == "aborted"
        assert "abort" in done[1]["error"]
        assert done[1]["summary"]["completed"] is False
        stored = client.get(url).json()
        assert stored["status"] == "aborted"
        assert any(e["kind"] == "abort" for e in stored["events"])
        # down by a landing plan (gcs.flight.safety.landing), or PX4's Land when none was ready in
        # its bound on a busy machine: the events say which
        assert {"landing_plan", "landing_fallback"} & {e["kind"] for e in stored["events"]}
        # Aborting a finished flight is a conflict, and everyone is down and disarmed.
        late = client.post(flight["links"]["abort"])
        assert late.status_code == 409
        assert late.json()["reason"].endswith("is not flying (status aborted)")
        wait_for(lambda: all(v["armed"] is False and v["position"][2] < 0.1
                             for v in client.get("/api/vehicles").json()["vehicles"]),
                 "every vehicle landed and disarmed", 15)
        assert client.delete(f"/api/missions/{mission['id']}").status_code == 204
        assert client.get(url).status_code == 404  # its flights went with it


def test_refusals(mock_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(mock_settings(mock_max_vehicles=4))) as client:  # --mock 4
        six = plan_mission(client, example("paper-circle6"))
        response = client.post(f"/api/missions/{six['id']}/flights")
        assert response.status_code == 409 and response.json()["field"] == "fleet"
        assert ("the plan has 6 vehicles, the mock fleet 4 (setting mock_vehicles): restart "
                "the service with --mock 6, or --mock auto") in response.json()["reason"]

        crossing = plan_mission(client, SHORT_CROSSING)
        url = f"/api/missions/{crossing['id']}/flights"
        for body, field in [({"policy": "explode"}, "policy"), ({"rate_hz": 500}, "rate_hz"),
                            ({"rate_hz": MIN_RATE_HZ}, "rate_hz"),
                            ({"rate_hz": MAX_RATE_HZ + 1}, "rate_hz"),
                            ({"stream_priority": "fastest"}, "stream_priority"),
                            ({"climb_speed": 0}, "climb_speed"), ({"prestream": 60}, "prestream"),
                            ({"colour": 1}, "colour")]:
            response = client.post(url, json=body)
            assert response.status_code == 422, response.text
            assert response.json()["field"] == field
        assert client.post("/api/missions/nope/flights").status_code == 404
        for path in ("/api/flights/nope", "/api/flights/nope/events",
                     "/api/flights/nope/record"):
            assert client.get(path).json()["field"] == "flight_id"
        assert client.post("/api/flights/nope/abort").status_code == 404

        # A plan that did not converge is never flown (here: stopped after one iteration).
        unfinished = copy.deepcopy(SHORT_CROSSING)
        unfinished.update(max_iterations=1, cost_threshold=1e-9)
        bad = plan_mission(client, unfinished)
        assert bad["plan_ok"] is False
        response = client.post(f"/api/missions/{bad['id']}/flights")
        assert response.status_code == 409 and response.json()["field"] == "mission_id"
        assert "only converged, verified plans are flown" in response.json()["reason"]
        assert client.get("/api/flights").json()["total"] == 0  # nothing was started


def test_no_fleet_means_no_flight(make_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(make_settings(mock_vehicles=0))) as client:
        assert client.get("/api/vehicles").json() == {
            "fleet": {"kind": "none", "vehicles": 0, "ids": [], "flying": None,
                      "world_origin": None, "grows_to": None, "vehicle_process": "running"},
            "vehicles": []}
        mission = plan_mission(client, SHORT_CROSSING)
        response = client.post(f"/api/missions/{mission['id']}/flights")
        assert response.status_code == 409
        assert "no fleet configured" in response.json()["reason"]


@pytest.mark.flight
def test_flights_survive_a_restart(flown: Flown) -> None:
    """A restarted service on the flight's database (the service that flew it has stopped)
    serves the finished flight, and marks one a killed server left 'starting' interrupted."""
    settings, flight, done = flown.settings, flown.created, flown.events[-1][1]
    assert done["status"] == "completed"
    # What a killed server leaves behind: a flight still 'starting'.
    store = Store(settings.database_url)
    orphan = store.create_flight(flown.mission["id"], "mock: a, b, c, d")
    store.close()
    with TestClient(create_app(settings)) as client:
        again = client.get(flight["links"]["self"]).json()
        assert again["status"] == "completed" and again["summary"] == done["summary"]
        assert client.get(flight["links"]["record"]).status_code == 200
        lost = client.get(f"/api/flights/{orphan.id}").json()
        assert lost["status"] == "interrupted"
        assert lost["error"] == "the service stopped during this flight"
        assert [kind for kind, _ in sse_events(client, f"/api/flights/{orphan.id}/events")] \
            == ["status", "done"]


@pytest.mark.flight
def test_pause_and_resume_through_the_api(mock_settings: Callable[..., Settings]) -> None:
    """Paused: status `paused`, the flight clock stands still and the fleet holds; resumed:
    the flight completes. Pausing twice, resuming a running flight or a finished one: 409."""
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, QUICK_CROSSING)
        flight = client.post(f"/api/missions/{mission['id']}/flights",
                                json=QUICK).json()
        url, links = flight["links"]["self"], flight["links"]
        assert client.post(links["resume"]).status_code == 409  # not paused
        # paused 1 s into the 6 s plan, the fleet moving
        wait_for(lambda: ((client.get(url).json()["live"] or {}).get("flight_time") or 0) > 1,
                 "the flight clock to pass 1 s", 30)
        paused = client.post(links["pause"])
        assert paused.status_code == 200, paused.text
        assert paused.json()["status"] == "paused"
        twice = client.post(links["pause"])
        assert twice.status_code == 409 and "cannot be paused (status paused)" in \
            twice.json()["reason"]
        first = client.get(url).json()
        # Time passes while paused, the fleet settling to its hold: then nobody moves more
        # than a few cm in half a second.
        seen: list[tuple[float, dict[str, Any]]] = []

        def settled() -> dict[str, Any] | None:
            now, live = time.monotonic(), client.get(url).json()
            seen.append((now, live))
            older = [doc for t, doc in seen if now - t >= 0.5]
            if not older:
                return None
            before = {v["id"]: v["position"] for v in older[-1]["live"]["vehicles"]}
            moved = max(np.linalg.norm(np.subtract(v["position"], before[v["id"]]))
                        for v in live["live"]["vehicles"])
            return live if moved < 0.1 else None

        later = wait_for(settled, "the paused fleet to settle to its hold", 15)
        assert later["status"] == "paused" and later["live"]["phase"] == "paused"
        assert later["live"]["flight_time"] == pytest.approx(first["live"]["flight_time"])
        assert later["live"]["min_separation_live"] > 1.0 - 0.1

        resumed = client.post(links["resume"])
        assert resumed.status_code == 200 and resumed.json()["status"] == "running"
        events = sse_events(client, links["events"])
        done = events[-1][1]
        assert done["status"] == "completed", done
        logged = [data["kind"] for kind, data in events if kind == "event"]
        assert logged.index("pause") < logged.index("resume") < logged.index("horizon")
        late = client.post(links["pause"])
        assert late.status_code == 409 and "is not flying" in late.json()["reason"]
        record = json.loads(client.get(links["record"]).content)
        assert len(record["pauses"]) == 1 and record["summary"]["completed"] is True


def test_executions_is_a_deprecated_alias_of_flights(make_settings: Callable[..., Settings]
                                                     ) -> None:
    """Every flight route answers the same under /api/executions, its former name, and the
    OpenAPI document marks exactly those (and the mission's /executions) deprecated."""
    settings = make_settings()
    with TestClient(create_app(settings)) as client:
        mission = plan_mission(client, SHORT_CROSSING)
        store = Store(settings.database_url)
        flown = store.create_flight(mission["id"], "mock: a, b")
        store.close()
        flight = client.get(f"/api/flights/{flown.id}").json()
        assert flight["links"]["self"] == f"/api/flights/{flown.id}"
        assert client.get(f"/api/executions/{flown.id}").json() == flight
        assert client.get("/api/flights").json()["flights"] == \
            client.get("/api/executions").json()["executions"]
        assert client.get(f"/api/missions/{mission['id']}/flights").json() == \
            client.get(f"/api/missions/{mission['id']}/executions").json() == [flight]
        refused = client.post(f"/api/executions/{flown.id}/pause")
        assert refused.status_code == 409 and refused.json()["field"] == "flight_id"
        assert client.get("/api/status").json()["statuses"]["execution"] == \
            client.get("/api/status").json()["statuses"]["flight"]

        paths = client.get("/openapi.json").json()["paths"]
    flights = {p for p in paths if p.startswith("/api/flights")}
    executions = {p for p in paths if p.startswith("/api/executions")}
    assert {p.replace("/api/executions", "/api/flights") for p in executions} == flights
    assert len(flights) == 9
    for path, operations in paths.items():
        former = path.startswith("/api/executions") or path.endswith("/executions")
        for method, operation in operations.items():
            assert operation.get("deprecated", False) is former, (method, path)
