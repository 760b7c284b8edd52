"""`GET /api/missions/{id}/geofence?format=qgc-plan`: the fence the vehicles are given, as a
QGroundControl .plan file, read back and checked against the fence builder; 409 without an
origin, 422 for a bad one, 404 for no mission."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gcs.api.app import create_app
from gcs.frames import Geodetic, geodetic_to_enu
from gcs.geofence import build_fence, fence_items
from gcs.service.settings import Settings
from planner import Plan
from tests.api.support import example


def _url(mission_id: str) -> str:
    return f"/api/missions/{mission_id}/geofence"


def test_the_fence_downloads_as_a_qgc_plan_placed_from_the_origin(
    shared_client: TestClient, planned: dict[str, Any]
) -> None:
    response = shared_client.get(_url(planned["id"]),
                                 params={"format": "qgc-plan", "origin": "47.5,19.05,120"})
    assert response.status_code == 200, response.text
    assert response.headers["content-disposition"] == (
        f'attachment; filename="geofence-{planned["id"]}.plan"')
    doc = response.json()
    assert doc["fileType"] == "Plan" and doc["version"] == 1
    assert doc["groundStation"] == "fleetplan"
    assert doc["mission"]["items"] == []
    assert doc["mission"]["plannedHomePosition"] == [47.5, 19.05, 120.0]
    assert doc["rallyPoints"] == {"version": 2, "points": []}
    fence = doc["geoFence"]
    assert fence["version"] == 2 and fence["circles"] == []
    [polygon] = fence["polygons"]
    assert polygon["inclusion"] is True and polygon["version"] == 1
    # the same places as the builder gives a vehicle at the world origin, to 1e-7 degrees
    origin = Geodetic(47.5, 19.05, 120.0)
    scenario = Plan.from_dict(planned["plan"]).scenario
    items = fence_items(build_fence(scenario.to_dict()), np.zeros(3), origin)
    got = np.array(polygon["polygon"])
    want = np.array([[i.x, i.y] for i in items]) * 1e-7
    assert np.max(np.abs(got - want)) <= 1.5e-7
    # and read back on the ground, the workspace's corners in the world frame
    lo, hi = scenario.limits.position_min, scenario.limits.position_max
    corners = [geodetic_to_enu(Geodetic(lat, lon, 120.0), origin)[:2] for lat, lon in got]
    assert np.allclose(corners, [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]],
                                 [lo[0], hi[1]]], atol=0.01)


def test_without_an_origin_is_409_and_a_bad_origin_422(
    shared_client: TestClient, planned: dict[str, Any]
) -> None:
    missing = shared_client.get(_url(planned["id"]))  # this service has no fleet
    assert missing.status_code == 409
    assert missing.json()["field"] == "origin"
    assert "?origin=LAT,LON" in missing.json()["reason"]
    bad = shared_client.get(_url(planned["id"]), params={"origin": "95,8"})
    assert bad.status_code == 422
    assert bad.json()["field"] == "origin"
    assert "latitude" in bad.json()["reason"]
    fmt = shared_client.get(_url(planned["id"]), params={"format": "kml", "origin": "47,8"})
    assert fmt.status_code == 422
    assert shared_client.get(_url("nope"), params={"origin": "47,8"}).status_code == 404


@pytest.fixture(scope="module")
def mock_client(module_mock_settings: Settings) -> Iterator[TestClient]:
    with TestClient(create_app(module_mock_settings)) as client:
        yield client


def test_a_mock_fleet_places_it_at_its_world_origin(mock_client: TestClient) -> None:
    created = mock_client.post("/api/missions?wait=60", json=example("paper-circle4"))
    assert created.status_code == 201, created.text
    origin = mock_client.get("/api/status").json()["fleet"]["world_origin"]
    assert origin is not None
    response = mock_client.get(_url(created.json()["id"]))
    assert response.status_code == 200, response.text
    doc = response.json()
    assert doc["mission"]["plannedHomePosition"] == [origin["lat"], origin["lon"],
                                                     origin["alt"]]
    [polygon] = doc["geoFence"]["polygons"]
    lo = Plan.from_dict(created.json()["plan"]).scenario.limits.position_min
    corner = geodetic_to_enu(Geodetic(*polygon["polygon"][0], origin["alt"]),
                             Geodetic(origin["lat"], origin["lon"], origin["alt"]))
    assert corner[:2] == pytest.approx(lo[:2], abs=0.01)


def test_the_fly_body_takes_the_geofence_option_and_refuses_another_value(
        mock_client: TestClient) -> None:
    created = mock_client.post("/api/missions?wait=60", json=example("paper-circle4"))
    assert created.status_code == 201, created.text
    refused = mock_client.post(f"/api/missions/{created.json()['id']}/flights",
                               json={"geofence": "maybe"})
    assert refused.status_code == 422
    assert "geofence" in refused.text
    assert mock_client.get("/api/flights").json()["total"] == 0  # nothing flew
    schema = mock_client.get("/openapi.json").json()["components"]["schemas"]["FlyRequest"]
    assert schema["properties"]["geofence"]["anyOf"][0]["enum"] == ["upload", "skip"]
