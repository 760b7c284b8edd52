"""`GET /api/missions/{id}/show.skyc`: the mission's verified plan as a Skybrush show, read
back independently; 404 for no mission, 409 without a verified plan, bounded like the other
exports (the keyframe limit, the export slots)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gcs.api.fanout import Slots
from planner import Plan
from tests.api.support import example
from tests.export.reader import evaluate, read_show


def _url(mission_id: str) -> str:
    return f"/api/missions/{mission_id}/show.skyc"


def test_a_planned_mission_downloads_as_a_show_that_is_its_plan(
    shared_client: TestClient, planned: dict[str, Any]
) -> None:
    assert planned["links"]["show_skyc"] == _url(planned["id"])
    response = shared_client.get(_url(planned["id"]))
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "application/zip"
    assert response.headers["content-disposition"] == (
        f'attachment; filename="show-{planned["id"]}.skyc"')
    show = read_show(response.content)
    assert show["meta"]["id"] == planned["id"]
    plan = Plan.from_dict(planned["plan"])
    times = np.linspace(0.0, plan.scenario.horizon, 1201)
    expected = plan.sample(times).position
    drones = show["swarm"]["drones"]
    assert [d["settings"]["name"] for d in drones] == plan.scenario.ids
    for n, drone in enumerate(drones):
        got = evaluate(drone["settings"]["trajectory"], times)
        assert np.max(np.linalg.norm(got - expected[n], axis=1)) <= 0.01
    located = shared_client.get(_url(planned["id"]), params={"origin": "47.5,19.05"})
    assert read_show(located.content)["environment"]["location"]["origin"] == [
        475000000, 190500000]


def test_no_such_mission_is_404(shared_client: TestClient) -> None:
    response = shared_client.get(_url("nope"))
    assert response.status_code == 404
    assert response.json()["field"] == "mission_id"


def test_a_mission_without_a_verified_plan_is_409(shared_client: TestClient) -> None:
    # Infeasible (jerk bound far too tight): planned, but its plan is not one to fly.
    scenario = example("paper-circle4")
    scenario["steps"] = 40
    scenario["limits"]["jerk_max"] = [0.05, 0.05, 0.05]
    reason = _refused(shared_client, scenario, plan_ok=False)
    assert "refusing to export the plan: its status is 'infeasible'" in reason


def _refused(client: TestClient, scenario: dict[str, Any], *, plan_ok: bool) -> str:
    """Plan `scenario` as a mission; its show is 409 naming the mission: the reason."""
    response = client.post("/api/missions?wait=60", json=scenario)
    assert response.status_code == 201, response.text
    mission = response.json()
    assert mission["plan_ok"] is plan_ok
    refused = client.get(_url(mission["id"]))
    assert refused.status_code == 409
    assert refused.json()["field"] == "mission_id"
    return str(refused.json()["reason"])


def test_a_plan_starting_moving_is_409_like_flying_it(shared_client: TestClient) -> None:
    """A verified plan from a moving start (a landing plan's kind) is no show: a show starts
    from a hover, the same verdict as `fleetplan fly` and `fleetplan export`."""
    scenario = example("paper-circle4")
    scenario["vehicles"][0]["start_velocity"] = [0.0, 0.3, 0.0]
    reason = _refused(shared_client, scenario, plan_ok=True)
    assert "starts moving (vehicles[0].start_velocity)" in reason


def test_a_mission_that_failed_has_no_plan_and_is_409(shared_client: TestClient) -> None:
    response = shared_client.post("/api/missions?wait=60&time_limit=0.01",
                                  json=example("random16"))
    assert response.status_code == 201, response.text
    assert response.json()["status"] == "failed"
    refused = shared_client.get(_url(response.json()["id"]))
    assert refused.status_code == 409
    assert "has no plan: planning exceeded its time limit" in refused.json()["reason"]


def test_a_bad_origin_is_422_naming_it(shared_client: TestClient,
                                       planned: dict[str, Any]) -> None:
    response = shared_client.get(_url(planned["id"]), params={"origin": "47.5"})
    assert response.status_code == 422
    assert response.json()["field"] == "origin"


def test_a_show_over_the_keyframe_limit_is_422_naming_the_setting(
    shared_client: TestClient, planned: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = shared_client.app.state.settings  # type: ignore[attr-defined]
    monkeypatch.setattr(settings, "max_trajectory_samples", 500)  # 4 x 151 keyframes > 500
    response = shared_client.get(_url(planned["id"]))
    assert response.status_code == 422
    body = response.json()
    assert body["field"] == "mission_id"
    assert "604 keyframes" in body["reason"] and "max_trajectory_samples" in body["reason"]


def test_exports_past_the_slot_limit_answer_503(shared_client: TestClient,
                                                planned: dict[str, Any]) -> None:
    exports: Slots = shared_client.app.state.exports  # type: ignore[attr-defined]
    held = exports.held
    exports.held = exports.limit
    try:
        busy = shared_client.get(_url(planned["id"]))
    finally:
        exports.held = held
    assert busy.status_code == 503
    assert busy.json()["field"] == "max_concurrent_exports"
    assert shared_client.get(_url(planned["id"])).status_code == 200
    assert exports.held == held  # released once sent
