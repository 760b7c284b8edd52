"""POST /api/missions with a plan made elsewhere (the CLI's plan file, or `{"plan": ...}`):
verified again on the server before it is stored as a planned mission; a malformed, unsafe
or oversized plan is 422 naming the field (and the vehicle by id), and nothing is stored."""

from __future__ import annotations

import copy
import json
from functools import cache
from typing import Any

import pytest
from fastapi.testclient import TestClient

import planner
from gcs.service.plan_worker import plan_json
from tests.api.support import example


@cache
def _plan_text() -> str:
    return plan_json(planner.plan(example("paper-circle2"), method="whole"))


def _plan() -> dict[str, Any]:
    return copy.deepcopy(json.loads(_plan_text()))


def _total(client: TestClient) -> int:
    return int(client.get("/api/missions").json()["total"])


@pytest.mark.parametrize("wrapped", [False, True])
def test_a_plan_made_elsewhere_is_stored_as_a_planned_mission(shared_client: TestClient,
                                                              wrapped: bool) -> None:
    plan = _plan()
    response = shared_client.post("/api/missions", json={"plan": plan} if wrapped else plan)
    assert response.status_code == 201, response.text
    mission = response.json()
    assert mission["status"] == "planned" and mission["plan_ok"] is True
    assert mission["plan_status"] == "converged" and mission["vehicle_count"] == 2
    stored = shared_client.get(response.headers["location"]).json()
    assert [v["id"] for v in stored["plan"]["vehicles"]] == ["uav1", "uav2"]
    assert stored["plan"]["vehicles"][0]["position"] == plan["vehicles"][0]["position"]
    assert stored["scenario"]["name"] == plan["scenario"]["name"]


def test_an_unsafe_plan_is_refused_whatever_its_own_verification_claims(
        shared_client: TestClient) -> None:
    plan = _plan()
    # the second vehicle flies the first one's path, one step behind: far too close
    first = plan["vehicles"][0]
    second = plan["vehicles"][1]
    second["position"] = [first["position"][0], *first["position"][:-1]]
    plan["verification"]["separated"] = True
    before = _total(shared_client)
    body = shared_client.post("/api/missions", json=plan).json()
    assert body["status"] == 422 and body["field"] == "plan"
    assert "this plan may not be flown" in body["reason"]
    assert "fleetplan plan" in body["reason"]
    assert _total(shared_client) == before


def test_a_plan_that_did_not_converge_is_refused(shared_client: TestClient) -> None:
    plan = _plan() | {"status": "max_iterations"}
    body = shared_client.post("/api/missions", json=plan).json()
    assert body["status"] == 422 and body["field"] == "plan"
    assert "its status is 'max_iterations'" in body["reason"]


def test_a_malformed_plan_names_the_field_and_the_vehicle(shared_client: TestClient) -> None:
    plan = _plan()
    plan["vehicles"][1]["position"] = plan["vehicles"][1]["position"][:-1]
    body = shared_client.post("/api/missions", json=plan).json()
    assert body["status"] == 422 and body["field"] == "vehicles[1].position"
    assert body["errors"][0]["vehicle"] == "uav2"
    assert "must have shape" in body["reason"]


def test_a_plan_over_the_servers_limits_lists_every_bound(shared_client: TestClient) -> None:
    plan = _plan()
    plan["scenario"] = example("random64") | {"steps": 401}
    body = shared_client.post("/api/missions", json=plan).json()
    assert body["status"] == 422
    reasons = {e["field"]: e["reason"] for e in body["errors"]}
    assert "64 vehicles exceed this server's limit of 16" in reasons["scenario.vehicles"]
    assert "401 steps exceed this server's limit of 400" in reasons["scenario.steps"]


def test_a_big_body_is_parsed_off_the_event_loop_all_the_same(
        shared_client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    from gcs.api import deps

    monkeypatch.setattr(deps, "PARSE_OFF_LOOP_BYTES", 0)  # every body counts as big
    response = shared_client.post("/api/missions", json=_plan())
    assert response.status_code == 201 and response.json()["plan_ok"] is True
    bad = shared_client.post("/api/missions", content=b"{not json",
                             headers={"content-type": "application/json"})
    assert bad.status_code == 400 and "not valid JSON" in bad.json()["reason"]
