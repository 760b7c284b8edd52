"""POST /api/flights/{id}/replan: its body's checks (422 naming the field), its refusals
(404, 409 when nothing flies the plan), the same access rules as the other flight commands,
and its documentation in the OpenAPI description; GET /api/flights/{id}/trajectory of a
flight that was not replanned. Replans flown on the mock fleet: test_replan_flight.py."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from typing import Any, NotRequired, get_origin

import numpy as np
import pytest
from fastapi.testclient import TestClient
from typing_extensions import get_type_hints

from gcs.api import create_app
from gcs.documents import ReplanDocument
from gcs.phases import DROP_ACTIONS, ReplanStatus
from gcs.replan_request import MAX_ENTRIES
from gcs.service.settings import Settings
from gcs.service.statuses import FlightStatus
from tests.api.support import OPERATOR, READER, example, plan_mission, refused


@pytest.fixture
def ended(make_settings: Callable[..., Settings]) -> Iterator[tuple[TestClient, str]]:
    """A service with no fleet and one stored flight that has ended (nothing flies)."""
    settings = make_settings(max_vehicles=4)
    with TestClient(create_app(settings)) as client:
        store = client.app.state.store  # type: ignore[attr-defined]
        mission = store.create_mission(example("paper-circle2"))
        row = store.create_flight(mission.id, "mock: a, b")
        store.update_flight(row.id, status=FlightStatus.COMPLETED, finished=True)
        yield client, f"/api/flights/{row.id}/replan"


def test_nothing_flying_is_409_naming_the_status(ended: tuple[TestClient, str]) -> None:
    client, url = ended
    refused(client.post(url, json={"goals": {"a": [1.0, 2.0, 3.0]}}), 409, "flight_id",
            "is not flying (status completed)")
    refused(client.post(url, json={"drop": ["a"], "drop_action": "hold"}), 409,
            "flight_id", "is not flying")
    refused(client.post("/api/flights/nope/replan", json={"drop": ["a"]}), 404,
            "flight_id", "")


@pytest.mark.parametrize(
    ("body", "field", "reason"),
    [
        ({}, "goals", "give new goals, vehicles to drop, or both"),
        ({"goals": {}, "drop": []}, "goals", "give new goals, vehicles to drop, or both"),
        ({"goals": {"a": [1, 2]}}, "goals.a", "at least 3 items"),
        ({"goals": {"a": [1, 2, 3, 4]}}, "goals.a", "at most 3 items"),
        ({"goals": {"a": [1, "2", 3]}}, "goals.a[1]", "valid number"),
        ({"goals": {"a": [1, True, 3]}}, "goals.a[1]", "valid number"),
        ({"goals": {"a": "1,2,3"}}, "goals.a", "valid list"),
        ({"goals": [[1, 2, 3]]}, "goals", "valid dictionary"),
        ({"goals": {"": [1, 2, 3]}}, "goals..[key]", "at least 1 character"),
        ({"goals": {"x" * 65: [1, 2, 3]}}, f"goals.{'x' * 65}.[key]", "at most 64"),
        ({"drop": "a"}, "drop", "valid list"),
        ({"drop": [""]}, "drop[0]", "at least 1 character"),
        ({"drop": ["a", "b", "a"]}, "drop[2]", "'a' is listed twice"),
        ({"drop": ["a"], "drop_action": "rtl"}, "drop_action", "'land' or 'hold'"),
        ({"drop": ["a"], "goals": {"a": [1, 2, 3]}}, "goals.a", "'a' is dropped"),
        ({"drop": ["a"], "then": "fly home"}, "then", "Extra inputs are not permitted"),
        ({"goals": {f"v{n}": [n, 0, 1] for n in range(5)}}, "goals",
         "5 entries exceed this server's fleet limit of 4 (setting max_vehicles)"),
        ({"drop": [f"v{n}" for n in range(5)]}, "drop", "fleet limit of 4"),
    ],
)
def test_bad_bodies_are_422_naming_the_field(
    ended: tuple[TestClient, str], body: dict[str, Any], field: str, reason: str
) -> None:
    client, url = ended
    refused(client.post(url, json=body), 422, field, reason)


@pytest.mark.parametrize("number", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_goals_are_422(ended: tuple[TestClient, str], number: str) -> None:
    # Python's JSON reader takes NaN and Infinity (and 1e999 overflows to inf): each is
    # refused by name, never passed on to the planner.
    client, url = ended
    content = '{"goals": {"uav2": [1.0, ' + number + ', 2.0]}}'
    refused(client.post(url, content=content, headers={"Content-Type": "application/json"}),
            422, "goals.uav2[1]", "finite number")


def test_a_missing_or_broken_body_is_refused(ended: tuple[TestClient, str]) -> None:
    client, url = ended
    refused(client.post(url), 422, "body", "Field required")
    refused(client.post(url, content="{", headers={"Content-Type": "application/json"}), 400,
            "body", "not valid JSON")


def test_bodies_over_the_size_limit_are_413(make_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(make_settings(max_body_bytes=2_000))) as client:
        body = json.dumps({"drop": [f"vehicle-{n}" for n in range(400)]})
        refused(client.post("/api/flights/nope/replan", content=body,
                            headers={"Content-Type": "application/json"}),
                413, "body", "exceeds 2000 bytes")


def test_replan_needs_the_operator_token_and_the_sites_own_origin(
    make_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(make_settings(api_token=OPERATOR, read_token=READER))) as client:
        url, body = "/api/flights/nope/replan", {"drop": ["a"]}
        refused(client.post(url, json=body), 401, "Authorization", "an API token is required")
        refused(client.post(url, json=body, headers={"Authorization": f"Bearer {READER}"}),
                403, "Authorization", "read-only token may not change anything")
        refused(client.post(url, json=body, headers={"Authorization": f"Bearer {OPERATOR}",
                                                     "Origin": "http://evil.example"}),
                403, "Origin", "cross-site request")
        refused(client.post(url, content=json.dumps(body), headers={
            "Authorization": f"Bearer {OPERATOR}", "Content-Type": "text/plain"}),
            415, "Content-Type", "must be JSON")
        # The operator's own request reaches the route (no such flight here).
        refused(client.post(url, json=body, headers={"Authorization": f"Bearer {OPERATOR}"}),
                404, "flight_id", "")


def test_the_route_is_documented(client: TestClient) -> None:
    schema = client.get("/openapi.json").json()
    post = schema["paths"]["/api/flights/{flight_id}/replan"]["post"]
    assert post["operationId"] == "replanFlight"
    assert {"202", "404", "409", "422"} <= set(post["responses"])
    body = schema["components"]["schemas"]["ReplanRequest"]
    assert set(body["properties"]) == {"goals", "drop", "drop_action"}


def test_the_replan_objects_schema_is_replan_document(client: TestClient) -> None:
    """The replan object the API documents is `ReplanDocument`, key for key: the keys a
    replan may lack until it switched are the only ones not required, and its status and
    drop action are the flight's own words."""
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    answer = schemas["ReplanOut"]["properties"]["replan"]["$ref"].rsplit("/", 1)[1]
    replan = schemas[answer]
    hints = get_type_hints(ReplanDocument, include_extras=True)
    assert set(replan["properties"]) == set(hints)
    assert set(replan["required"]) == {k for k, hint in hints.items()
                                       if get_origin(hint) is not NotRequired}
    assert set(replan["required"]) < set(hints)
    status = replan["properties"]["status"]["$ref"].rsplit("/", 1)[1]
    assert schemas[status]["enum"] == [s.value for s in ReplanStatus]
    assert replan["properties"]["drop_action"]["enum"] == list(DROP_ACTIONS)


def test_a_flight_without_replans_flies_its_missions_trajectory(client: TestClient) -> None:
    mission = plan_mission(client, example("paper-circle2"))
    store = client.app.state.store  # type: ignore[attr-defined]
    row = store.create_flight(mission["id"], "mock: a, b")
    store.update_flight(row.id, status=FlightStatus.COMPLETED, finished=True)
    url = f"/api/flights/{row.id}/trajectory"
    flown = client.get(url, params={"rate": 5})
    assert flown.status_code == 200, flown.text
    doc = flown.json()
    planned = client.get(f"/api/missions/{mission['id']}/trajectory", params={"rate": 5}).json()
    assert (doc["flight_id"], doc["mission_id"]) == (row.id, mission["id"])
    assert doc["t"] == pytest.approx(planned["t"])
    assert [v["id"] for v in doc["vehicles"]] == [v["id"] for v in planned["vehicles"]]
    for got, want in zip(doc["vehicles"], planned["vehicles"], strict=True):
        assert np.allclose(got["position"], want["position"])
    assert doc["switches"] == [] and doc["dropped"] == {}
    refused(client.get(url, params={"rate": 10_000}), 422, "rate", "must be at most")
    refused(client.get(url, params={"rate": 0}), 422, "rate", "greater than 0")
    refused(client.get("/api/flights/nope/trajectory"), 404, "flight_id", "")


def test_a_replan_names_at_most_max_entries(ended: tuple[TestClient, str]) -> None:
    client, url = ended
    many = [f"v{n}" for n in range(MAX_ENTRIES + 1)]
    refused(client.post(url, json={"drop": many}), 422, "drop", f"at most {MAX_ENTRIES} items")
    refused(client.post(url, json={"goals": {v: [0, 0, 1] for v in many}}), 422, "goals",
            f"at most {MAX_ENTRIES} items")
