"""The planning method through the REST API: the scenario's `method` key, auto's race inside
a Dask worker process (daemonic: `planner.methods.race` forks without `multiprocessing`), and the
plan's `method` and `attempts`."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from tests.api.support import example, plan_mission, sse_events


def _outcomes(plan: dict[str, Any]) -> dict[str, str]:
    return {a["method"]: a["outcome"] for a in plan["attempts"]}


def test_auto_races_both_methods_in_the_worker_and_the_plan_says_which_won(
        client: TestClient) -> None:
    """With obstacles the two methods race at once (no head start): the worker forks an arm
    for each, the first verified plan wins, and the other is recorded as cancelled or
    failed. Every progress record says which method it belongs to."""
    response = client.post("/api/missions?wait=0", json=example("pillar-circle8"))
    assert response.status_code == 202, response.text
    mission = response.json()
    assert mission["scenario"]["method"] == "auto"
    events = sse_events(client, mission["links"]["events"])
    assert events[-1] == ("done", events[-1][1]) and events[-1][1]["status"] == "planned"
    labels = {data["method"] for kind, data in events if kind == "iteration"}
    assert labels and labels <= {"whole", "prioritized"}
    plan = client.get(f"/api/missions/{mission['id']}").json()["plan"]
    assert plan["status"] == "converged" and plan["method"] in ("whole", "prioritized")
    outcomes = _outcomes(plan)
    assert outcomes[plan["method"]] == "won"
    loser = "whole" if plan["method"] == "prioritized" else "prioritized"
    assert outcomes[loser] in ("cancelled", "failed")
    for attempt in plan["attempts"]:
        assert set(attempt) == {"method", "outcome", "reason", "seconds"}
        assert attempt["seconds"] >= 0.0


def test_the_scenario_method_is_planned_and_echoed(client: TestClient) -> None:
    mission = plan_mission(client, example("paper-circle4") | {"method": "prioritized"})
    assert mission["scenario"]["method"] == "prioritized"
    plan = mission["plan"]
    assert plan["method"] == "prioritized" and _outcomes(plan)["prioritized"] == "won"
    assert plan["scenario"]["method"] == "prioritized"


def test_an_unknown_method_is_a_422_naming_the_field(client: TestClient) -> None:
    response = client.post("/api/missions?wait=0", json=example("paper-circle4")
                           | {"method": "fastest"})
    assert response.status_code == 422
    body = response.json()
    assert body["field"] == "method"
    assert "must be one of 'auto', 'whole', 'prioritized'" in body["reason"]


def test_the_schema_knows_the_method_and_the_attempts(client: TestClient) -> None:
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    method = schemas["Scenario"]["properties"]["method"]
    assert method["enum"] == ["auto", "whole", "prioritized"] and method["default"] == "auto"
    assert "method" not in schemas["Scenario"]["required"]
    attempt = schemas["Attempt"]
    assert attempt["properties"]["outcome"]["enum"] == ["won", "declined", "failed",
                                                         "cancelled"]
    assert {"method", "attempts"} <= set(schemas["Plan"]["properties"])
