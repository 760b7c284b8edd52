"""Fleet commands through the API (POST /api/fleet/commands, /api/vehicles/{id}/commands) on
in-process mock PX4 vehicles: a fleet left hovering by an abort with
hold, landed by a fleet command; and every refusal."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.phases import FLEET_COMMANDS
from gcs.service.settings import Settings
from gcs.sim import DEFAULT_WORLD_ORIGIN
from tests.api.support import QUICK, QUICK_CROSSING, plan_mission, sse_events
from tests.support.waiting import wait_for


@pytest.mark.flight
def test_a_fleet_left_hovering_after_a_hold_abort_is_landed_by_a_fleet_command(
    mock_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, QUICK_CROSSING)
        flight = client.post(f"/api/missions/{mission['id']}/flights").json()
        url = flight["links"]["self"]
        wait_for(lambda: (client.get(url).json()["live"] or {}).get("phase") == "flying",
                 "the flight clock", 30)
        # while a flight is under way, its own abort is the way: no fleet command
        busy = client.post("/api/fleet/commands", json={"command": "land"})
        assert busy.status_code == 409 and busy.json()["field"] == "fleet"
        assert "abort" in busy.json()["reason"]

        response = client.post(flight["links"]["abort"], json={"action": "hold"})
        assert response.status_code == 202
        done = sse_events(client, flight["links"]["events"])[-1]
        assert done[1]["status"] == "aborted"
        # The flight is over; the vehicles hover in PX4 Hold, and abort has nothing to abort.
        assert client.post(flight["links"]["abort"]).status_code == 409
        hovering = wait_for(
            lambda: (lambda vs: vs if all(v["armed"] and v["mode"] == "AUTO.LOITER"
                                          for v in vs) else None)(
                client.get("/api/vehicles").json()["vehicles"]),
            "the monitor to see the hovering fleet", 10)
        assert all(v["position"][2] > 0.8 for v in hovering)
        ids = [v["id"] for v in hovering]

        # refusals: nothing is sent
        refused = client.post("/api/fleet/commands", json={"command": "disarm"})
        assert refused.status_code == 409 and refused.json()["field"] == "force"
        assert "in the air" in refused.json()["reason"]
        unconfirmed = client.post("/api/fleet/commands", json={"command": "terminate"})
        assert unconfirmed.status_code == 422 and unconfirmed.json()["field"] == "confirm"
        for body, field in [({"command": "explode"}, "command"), ({}, "command"),
                            ({"command": "land", "vehicles": ["zz"]}, "vehicles"),
                            ({"command": "land", "confirm": "yes"}, "confirm"),
                            ({"command": "land", "colour": 1}, "colour")]:
            bad = client.post("/api/fleet/commands", json=body)
            assert bad.status_code == 422, (body, bad.text)
            assert bad.json()["field"] == field, (body, bad.json())
        missing = client.post("/api/vehicles/zz/commands", json={"command": "land"})
        assert missing.status_code == 404 and missing.json()["field"] == "vehicle_id"
        assert all(v["armed"] for v in client.get("/api/vehicles").json()["vehicles"])

        # one vehicle first, then the rest of the fleet
        one = client.post(f"/api/vehicles/{ids[0]}/commands", json={"command": "land"})
        assert one.status_code == 200, one.text
        body = one.json()
        assert body["done"] is True and [v["vehicle"] for v in body["vehicles"]] == ids[:1]
        assert body["vehicles"][0]["mode"] == "AUTO.LAND"
        rest = client.post("/api/fleet/commands",
                           json={"command": "land", "vehicles": ids[1:]}).json()
        assert rest["done"] is True
        assert {v["vehicle"] for v in rest["vehicles"]} == set(ids[1:])
        assert all(v["mode"] == "AUTO.LAND" for v in rest["vehicles"])
        wait_for(lambda: all(v["armed"] is False and v["position"][2] < 0.1
                             for v in client.get("/api/vehicles").json()["vehicles"]),
                 "every vehicle landed and disarmed", 20)
        # and the landed fleet can fly again
        again = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK)
        assert again.status_code == 201, again.text
        final = sse_events(client, again.json()["links"]["events"])[-1]
        assert final[1]["status"] == "completed", final


def test_fleet_commands_without_a_fleet(make_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(make_settings())) as client:
        response = client.post("/api/fleet/commands", json={"command": "hold"})
        assert response.status_code == 409 and response.json()["field"] == "fleet"
        assert "no fleet" in response.json()["reason"]
        # what a client builds its buttons from: every command the POST accepts, described
        listed = client.get("/api/fleet/commands").json()
        assert [c["command"] for c in listed] == list(FLEET_COMMANDS)
        assert [c["command"] for c in listed if c["needs"]] == ["disarm", "terminate"]


@pytest.mark.flight
def test_vehicle_health_and_the_preflight_gate(mock_settings: Callable[..., Settings]) -> None:
    """GET /api/vehicles shows battery, gps, health and link quality per vehicle; Fly is
    refused (409, naming the vehicle and the reason) for a vehicle low on battery, unless
    the override is asked for, which the flight's events record."""
    with TestClient(create_app(mock_settings())) as client:
        vehicles = wait_for(
            lambda: (lambda vs: vs if all(v["gps"]["fix_type"] == 3
                                          and v["health"]["prearm_ok"] for v in vs) else None)(
                client.get("/api/vehicles").json()["vehicles"]),
            "every vehicle's GPS_RAW_INT and settled SYS_STATUS", 10)
        # the world frame's geodetic origin (the mock's), for a page's coordinates and scale
        mock_origin = DEFAULT_WORLD_ORIGIN  # the mocks' own (the service's mocks keep it)
        assert client.get("/api/vehicles").json()["fleet"]["world_origin"] == {
            "lat": mock_origin.lat, "lon": mock_origin.lon, "alt": mock_origin.alt}
        for v in vehicles:
            assert v["battery"]["remaining_pct"] == 100 and v["battery"]["voltage"] > 16
            assert v["gps"]["h_acc"] == pytest.approx(0.05)
            assert v["health"]["unhealthy"] == []
            assert v["link_quality"]["received"] > 10 and v["link_quality"]["lost"] == 0
        # inject a fault into the service's mock vehicle 2, in its vehicle process
        app = cast(Any, client.app)
        client.portal.call(app.state.fleet.vehicle_process.call,  # type: ignore[union-attr]
                           "inject_mock_fault", 2, "battery", 15.0)
        wait_for(lambda: client.get("/api/vehicles").json()["vehicles"][2]["battery"]
                 ["remaining_pct"] == 15, "the low battery to be reported", 5)

        mission = plan_mission(client, QUICK_CROSSING)
        url = f"/api/missions/{mission['id']}/flights"
        refused = client.post(url, json={"hold_at_goal": 0.5})
        assert refused.status_code == 409, refused.text
        reason = refused.json()["reason"]
        assert "uav3" in reason and "battery 15% (below 30%)" in reason
        assert client.get("/api/flights").json()["flights"] == []  # nothing was started

        allowed = client.post(url, json={**QUICK, "preflight": "override"})
        assert allowed.status_code == 201, allowed.text
        events = sse_events(client, allowed.json()["links"]["events"])
        assert events[-1][1]["status"] == "completed", events[-1]
        overrides = [d for kind, d in events if kind == "event"
                     and d["kind"] == "preflight_override"]
        assert [d["vehicle"] for d in overrides] == ["c"]  # the airframe kept its battery
        assert "battery 15%" in overrides[0]["detail"]
