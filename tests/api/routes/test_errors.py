"""Every error path: status code, and a JSON body naming the field and the reason."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient
from httpx import Response

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import example


def assert_error(response: Response, status: int, field: str | None, reason: str) -> None:
    """The error body: status, field, a reason containing `reason`, and the list of errors."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/json")
    body = response.json()
    assert body["status"] == status
    assert body["field"] == field, body
    assert reason in body["reason"], body
    first = body["errors"][0] if body["errors"] else {}
    assert {k: v for k, v in first.items() if k != "vehicle"} == {
        "field": field, "reason": body["reason"]}


def edited(change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    scenario = copy.deepcopy(example("paper-circle4"))
    change(scenario)
    return scenario


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def change(scenario: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        target: Any = scenario
        for key in parents:
            target = target[int(key)] if key.isdigit() else target[key]
        target[int(last) if last.isdigit() else last] = value

    return change


def _delete(key: str) -> Callable[[dict[str, Any]], None]:
    return lambda scenario: scenario.pop(key)


BAD_SCENARIOS = [
    # Shape (the schema derived from the planner's types) ...
    (_set("colour", "red"), "colour", "unknown key"),
    (_set("limits.max_speed", 3), "limits.max_speed", "unknown key"),
    (_delete("dt"), "dt", "is required"),
    (_set("dt", "fast"), "dt", "must be a number, got string"),
    (_set("steps", 1.5), "steps", "must be an integer, got 1.5"),
    (_set("vehicles.0.start", [1, 2]), "vehicles[0].start", "list of 3 numbers"),
    (_set("vehicles.2.goal", [1, 2, 3, 4]), "vehicles[2].goal", "list of 3 numbers"),
    (_set("vehicles.1.id", 7), "vehicles[1].id", "must be a string"),
    (_set("vehicles", {"uav1": {}}), "vehicles", "must be a list"),
    # ... and meaning (the planner's validation).
    (_set("vehicles.1.goal", [9.0, 1.0, 1.0]), "vehicles[1].goal", "outside the workspace"),
    (_set("vehicles.1.id", "uav1"), "vehicles[1].id", "duplicate id"),
    (_set("vehicles.3.start", [2.5, 4.6, 1.9]), "vehicles[3].start", "closer than min_separation"),
    (_set("dt", -0.2), "dt", "must be positive"),
    (_set("steps", 10), "vehicles[0].goal", "cannot be reached within the horizon"),
    (_set("vehicles", []), "vehicles", "at least one vehicle"),
    (_set("limits.position_max", [5, 5, -1]), "limits.position_max[2]", "must be greater"),
    (_set("limits.velocity_max", [2, 0, 2]), "limits.velocity_max[1]", "must be positive"),
    (_set("name", ""), "name", "non-empty"),
]


def test_each_error_names_its_vehicle_by_id_and_a_mistyped_key_its_nearest(
    shared_client: TestClient,
) -> None:
    def broken(scenario: dict[str, Any]) -> None:
        scenario["min_seperation"] = scenario.pop("min_separation")
        scenario["vehicles"][2]["goal"] = [1, 2]

    body = shared_client.post("/api/missions", json=edited(broken)).json()
    assert body["status"] == 422
    by_field = {e["field"]: e for e in body["errors"]}
    assert by_field["min_seperation"]["reason"] == "unknown key (did you mean 'min_separation'?)"
    assert "vehicle" not in by_field["min_seperation"]
    assert by_field["vehicles[2].goal"]["vehicle"] == "uav3"
    meaning = shared_client.post("/api/missions",
                                 json=edited(_set("vehicles.1.goal", [9.0, 1.0, 1.0]))).json()
    assert meaning["errors"][0]["field"] == "vehicles[1].goal"
    assert meaning["errors"][0]["vehicle"] == "uav2"


@pytest.mark.parametrize(("change", "field", "reason"), BAD_SCENARIOS)
def test_invalid_scenarios_are_422_naming_the_field(
    shared_client: TestClient, change: Callable[[dict[str, Any]], None], field: str, reason: str
) -> None:
    before = shared_client.get("/api/missions").json()["total"]
    response = shared_client.post("/api/missions", json=edited(change))
    assert_error(response, 422, field, reason)
    assert shared_client.get("/api/missions").json()["total"] == before  # nothing stored


def test_server_limits_are_enforced_with_the_setting_named(shared_client: TestClient) -> None:
    # shared_client allows 16 vehicles and 400 steps.
    response = shared_client.post("/api/missions", json=example("random64"))
    assert_error(response, 422, "vehicles", "64 vehicles exceed this server's limit of 16")
    assert "max_vehicles" in response.json()["reason"]
    response = shared_client.post("/api/missions", json=edited(_set("steps", 401)))
    assert_error(response, 422, "steps", "401 steps exceed this server's limit of 400")


def test_body_size_limit(shared_client: TestClient) -> None:
    # the shared app allows 200 kB, and 400 kB to POST /api/missions (a plan to fly)
    scenario = edited(_set("name", "x" * 500_000))
    response = shared_client.post("/api/missions", json=scenario)
    assert_error(response, 413, "body", "request body exceeds 400000 bytes")
    assert "(setting max_plan_body_bytes)" in response.json()["reason"]
    response = shared_client.post("/api/missions/nope/flights",
                                  json=edited(_set("name", "x" * 300_000)))
    assert_error(response, 413, "body", "request body exceeds 200000 bytes")
    assert "(setting max_body_bytes)" in response.json()["reason"]

    def chunks() -> Any:  # no Content-Length: counted as it arrives
        for _ in range(50):
            yield b" " * 10_000

    response = shared_client.post(
        "/api/missions", content=chunks(), headers={"content-type": "application/json"}
    )
    assert_error(response, 413, "body", "request body exceeds 400000 bytes")


@pytest.mark.parametrize(
    ("body", "reason"),
    [(b"{not json", "not valid JSON"), (b"", "is required"), (b"[1, 2]", "must be a JSON object"),
     (b'{"dt": NaN}', "not valid JSON")],
)
def test_malformed_bodies(shared_client: TestClient, body: bytes, reason: str) -> None:
    response = shared_client.post(
        "/api/missions", content=body, headers={"content-type": "application/json"}
    )
    expected = 400 if reason == "not valid JSON" else 422
    assert_error(response, expected, "body", reason)


@pytest.mark.parametrize(
    ("method", "path", "field"),
    [
        ("GET", "/api/missions/nope", "mission_id"),
        ("DELETE", "/api/missions/nope", "mission_id"),
        ("GET", "/api/missions/nope/trajectory", "mission_id"),
        ("GET", "/api/missions/nope/plan", "mission_id"),
        ("GET", "/api/missions/nope/events", "mission_id"),
        ("GET", "/api/examples/nope", "name"),
        ("GET", "/api/no-such-thing", "path"),
    ],
)
def test_unknown_resources_are_404(
    shared_client: TestClient, method: str, path: str, field: str
) -> None:
    response = shared_client.request(method, path)
    assert_error(response, 404, field, "")
    assert response.json()["reason"]


def test_wrong_method_is_405_with_the_error_body(shared_client: TestClient) -> None:
    response = shared_client.put("/api/missions")
    assert response.status_code == 405
    assert response.json()["reason"] == "Method Not Allowed"
    assert response.headers["allow"] == "GET, POST"


@pytest.mark.parametrize(
    ("query", "field", "reason"),
    [
        ({"rate": 0}, "rate", "greater than 0"),
        ({"rate": 101}, "rate", "at most 100 Hz"),
        ({"rate": "fast"}, "rate", "valid number"),
        ({"format": "xml"}, "format", "'json', 'csv' or 'show-csv'"),
    ],
)
def test_bad_trajectory_queries(
    shared_client: TestClient, query: dict[str, Any], field: str, reason: str
) -> None:
    mission = shared_client.post("/api/missions?wait=60", json=example("paper-circle2")).json()
    response = shared_client.get(f"/api/missions/{mission['id']}/trajectory", params=query)
    assert_error(response, 422, field, reason)


@pytest.mark.parametrize(
    ("query", "field"),
    [({"limit": 0}, "limit"), ({"offset": -1}, "offset"), ({"limit": "x"}, "limit")],
)
def test_bad_list_queries(shared_client: TestClient, query: dict[str, Any], field: str) -> None:
    assert_error(shared_client.get("/api/missions", params=query), 422, field, "")


def test_bad_wait_is_422(shared_client: TestClient) -> None:
    response = shared_client.post("/api/missions?wait=-1", json=example("paper-circle2"))
    assert_error(response, 422, "wait", "greater than or equal to 0")


def test_too_many_samples_is_422_with_the_rate_to_use(
    make_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(make_settings(max_trajectory_samples=10_000))) as client:
        mission = client.post("/api/missions?wait=60", json=example("paper-circle8")).json()
        # 8 vehicles x (30 s x 100 Hz + 1 samples) = 24008 > 10000
        response = client.get(f"/api/missions/{mission['id']}/trajectory?rate=100")
        assert_error(
            response, 422, "rate", "more than the limit 10000 (setting max_trajectory_samples)"
        )


def test_conflicts_while_planning(make_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(make_settings())) as client:
        response = client.post("/api/missions?wait=0", json=example("random64"))
        assert response.status_code == 202
        mission_id = response.json()["id"]
        url = f"/api/missions/{mission_id}"
        assert_error(client.get(f"{url}/trajectory"), 409, "mission_id", "still planning")
        assert_error(client.get(f"{url}/plan"), 409, "mission_id", "still planning")
        assert client.get(url).json()["status"] == "planning"
        # DELETE while planning cancels the plan (tests/service/test_jobs_api.py).
