"""`steps: "auto"` through POST /api/missions: the service passes it to the planner with a
`max_horizon` that keeps the search within its own horizon and steps limits, the mission
records the chosen steps, and bad values are 422 naming the field."""

from __future__ import annotations

import copy
from typing import Any

from fastapi.testclient import TestClient

from planner import Plan
from tests.api.support import OUT_AND_BACK, example, refused

#: `shared_client`'s max_steps (400) at dt = 0.2 s.
SERVER_BUDGET_S = 80.0


def _auto(**extra: Any) -> dict[str, Any]:
    return {**example("paper-circle4"), "steps": "auto", **extra}


def test_an_auto_mission_is_planned_at_the_chosen_horizon(shared_client: TestClient) -> None:
    response = shared_client.post("/api/missions?wait=60", json=_auto())
    assert response.status_code == 201, response.text
    mission = response.json()
    assert mission["status"] == "planned" and mission["plan_ok"] is True, mission["error"]
    # the scenario as stored: auto, with the max_horizon this server allows filled in
    assert mission["scenario"]["steps"] == "auto"
    assert mission["scenario"]["max_horizon"] == SERVER_BUDGET_S
    plan = Plan.from_dict(shared_client.get(mission["links"]["plan"]).json())
    chosen = plan.horizon["chosen_steps"]
    assert plan.ok and plan.scenario.steps == chosen
    assert plan.horizon["max_horizon"] == SERVER_BUDGET_S
    listed = shared_client.get(f"/api/missions/{mission['id']}").json()
    assert listed["steps"] == chosen
    assert listed["horizon_s"] == chosen * 0.2


def test_a_max_horizon_past_the_server_limits_is_422(shared_client: TestClient) -> None:
    refused(shared_client.post("/api/missions", json=_auto(max_horizon=200)), 422,
            "max_horizon", f"give at most {SERVER_BUDGET_S:g} s")


def test_a_bad_steps_value_is_422_naming_it(shared_client: TestClient) -> None:
    refused(shared_client.post("/api/missions", json=_auto(steps="soon")), 422, "steps",
            '"auto"')
    refused(shared_client.post("/api/missions", json=_auto(steps=[5])), 422, "steps",
            "must be an integer, got array")


def test_a_max_horizon_too_short_for_the_moves_is_422(shared_client: TestClient) -> None:
    refused(shared_client.post("/api/missions", json=_auto(max_horizon=1.0)), 422,
            "max_horizon", "raise max_horizon")


def test_a_sequence_with_an_auto_leg_shares_the_server_budget(shared_client: TestClient
                                                              ) -> None:
    body = copy.deepcopy(OUT_AND_BACK)
    body["formations"][2]["duration"] = "auto"
    response = shared_client.post("/api/missions?wait=60", json=body)
    assert response.status_code == 201, response.text
    mission = response.json()
    assert mission["plan_ok"] is True, mission["error"]
    plan = Plan.from_dict(shared_client.get(mission["links"]["plan"]).json())
    auto_leg = plan.sequence["legs"][1]
    # the budget left after the fixed leg and the holds: 80 - 6 - 3 x 0.4 s
    assert auto_leg["horizon"]["max_horizon"] == SERVER_BUDGET_S - 6.0 - 1.2
    assert plan.scenario.steps == 3 * 2 + 30 + auto_leg["steps"]
    body["max_horizon"] = 100
    refused(shared_client.post("/api/missions", json=body), 422, "max_horizon",
            "give at most")
