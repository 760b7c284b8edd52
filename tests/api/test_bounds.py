"""Every scenario quantity that multiplies work is bounded before anything is allocated, the
field and the setting named; answers are strict JSON (no NaN or Infinity)."""

from __future__ import annotations

import copy
import json
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.replan_request import MAX_ENTRIES
from gcs.service.events import MAX_BACKLOG
from gcs.service.limits import (
    FIXED_LIMITS,
    LIMIT_NAMES,
    MAX_SEQUENCE_LEGS,
    trajectory_sample_count,
)
from gcs.service.plans import sample_times
from tests.api.support import example


def _strict_json(text: str) -> Any:
    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} in a JSON answer")

    return json.loads(text, parse_constant=refuse)


def _scenario(**changes: Any) -> dict[str, Any]:
    scenario = copy.deepcopy(example("paper-circle2"))
    for key, value in changes.items():
        if key.startswith("limits."):
            scenario["limits"][key.removeprefix("limits.")] = value
        else:
            scenario[key] = value
    return scenario


@pytest.mark.parametrize(
    ("changes", "field", "reason"),
    [
        # Absurd values that would otherwise plan for ever, fail inside, or put Infinity
        # into JSON.
        ({"dt": 10_000, "steps": 1000}, "dt", "must be between 0.01 and 5 s"),
        ({"dt": 1e8}, "dt", "(settings dt_min, dt_max)"),
        ({"dt": 1e308}, "dt", "got 1e+308"),
        ({"dt": 0.001}, "dt", "must be between 0.01 and 5 s"),
        ({"dt": 5.0, "steps": 400}, "steps", "horizon steps * dt = 2000 s exceeds this "
         "server's limit of 900 s (setting max_horizon_s)"),
        ({"limits.position_max": [1e308, 5, 3]}, "limits.position_max[0]",
         "1e+308 m is farther than 10000 m from the origin (setting max_coordinate_m)"),
        ({"limits.position_min": [0, -20_000, 0]}, "limits.position_min[1]", "10000 m"),
        # `steps` errors quote the limit in force (max_steps 400 here), not the planner's.
        ({"steps": 2}, "steps", "must be between 3 and 400 on this server, got 2"),
        ({"steps": 6000, "dt": 0.1}, "steps", "6000 steps exceed this server's limit of 400"),
    ],
)
def test_work_bounds_name_the_field_and_setting(
    shared_client: TestClient, changes: dict[str, Any], field: str, reason: str
) -> None:
    before = shared_client.get("/api/missions").json()["total"]
    response = shared_client.post("/api/missions", json=_scenario(**changes))
    assert response.status_code == 422, response.text
    errors = {e["field"]: e["reason"] for e in _strict_json(response.text)["errors"]}
    assert reason in errors[field], errors
    assert shared_client.get("/api/missions").json()["total"] == before


def test_every_exceeded_bound_is_reported_at_once(shared_client: TestClient) -> None:
    scenario = _scenario(dt=1e8, **{"limits.position_max": [1e308, 5, 1e9]})
    scenario["vehicles"][1]["goal"] = [3.0, -50_000.0, 1.0]
    response = shared_client.post("/api/missions", json=scenario)
    assert response.status_code == 422
    fields = [e["field"] for e in response.json()["errors"]]
    assert fields == ["dt", "limits.position_max[0]", "limits.position_max[2]",
                      "vehicles[1].goal[1]"]


def test_every_shape_error_is_reported_at_once(shared_client: TestClient) -> None:
    scenario = _scenario(dt="fast", colour="red")
    del scenario["steps"]
    scenario["vehicles"][0]["start"] = [1, 2]
    scenario["vehicles"][1]["id"] = 7
    response = shared_client.post("/api/missions", json=scenario)
    assert response.status_code == 422
    errors = {e["field"]: e["reason"] for e in response.json()["errors"]}
    assert errors == {
        "colour": "unknown key", "steps": "is required", "dt": "must be a number, got string",
        "vehicles[0].start": "must be a list of 3 numbers [x, y, z]",
        "vehicles[1].id": "must be a string, got number",
    }


def test_every_problem_of_the_settings_is_reported_at_once(shared_client: TestClient) -> None:
    scenario = _scenario(dt=-1.0, min_separation=0.0, assignment="any")
    response = shared_client.post("/api/missions", json=scenario)
    assert response.status_code == 422, response.text
    body = response.json()
    assert [e["field"] for e in body["errors"]] == ["dt", "min_separation", "assignment"]
    assert (body["field"], body["errors"][2]["reason"]) == (
        "dt", "must be 'fixed' or 'free', got 'any'")


def test_a_valid_mission_document_is_strict_json(shared_client: TestClient) -> None:
    response = shared_client.post("/api/missions?wait=60", json=example("paper-circle2"))
    assert response.status_code == 201
    mission = _strict_json(response.text)
    assert mission["horizon_s"] == pytest.approx(30.0)
    _strict_json(shared_client.get(f"/api/missions/{mission['id']}").text)


@pytest.mark.parametrize(
    ("horizon", "rate"), [(30.0, 20.0), (30.0, 7.0), (0.6, 3.0), (29.9, 100.0), (1e7, 20.0)]
)
def test_the_export_size_is_counted_without_allocating(horizon: float, rate: float) -> None:
    count = trajectory_sample_count(horizon, rate, vehicles=3)
    if horizon * rate < 1e6:
        assert count == 3 * len(sample_times(horizon, rate))
    else:  # 2e8 samples: counted, never built
        assert count == 3 * (int(horizon * rate) + 1)


def test_status_publishes_every_limit_in_force(shared_client: TestClient) -> None:
    limits = shared_client.get("/api/status").json()["limits"]
    assert set(limits) == {*LIMIT_NAMES, *FIXED_LIMITS}
    # among them the bounds on work and fan-out a client must know before it asks
    assert {"max_trajectory_samples", "plan_queue_max", "dt_min", "dt_max", "max_horizon_s",
            "max_coordinate_m", "max_concurrent_exports", "max_event_streams",
            "max_event_streams_per_resource", "request_timeout_s"} <= set(limits)
    settings = shared_client.app.state.settings  # type: ignore[attr-defined]
    for name in LIMIT_NAMES:
        assert limits[name] == getattr(settings, name), name
    assert limits["max_sequence_legs"] == MAX_SEQUENCE_LEGS
    assert limits["max_replan_entries"] == MAX_ENTRIES  # what a replan body is checked against
    assert limits["max_event_backlog"] == MAX_BACKLOG  # where a stalled event stream ends
    # The values are the shared app's own (not the defaults) ...
    assert (limits["max_steps"], limits["max_vehicles"]) == (400, 16)
    # ... and the ones its answers quote.
    too_many = _scenario(steps=limits["max_steps"] + 1)
    reason = shared_client.post("/api/missions", json=too_many).json()["reason"]
    assert f"limit of {limits['max_steps']} " in reason


def test_more_obstacles_than_the_setting_are_refused(shared_client: TestClient) -> None:
    limit = shared_client.app.state.settings.max_obstacles  # type: ignore[attr-defined]
    box = {"box": {"min": [0.0, 0.0, 0.0], "max": [0.1, 0.1, 0.1]}}
    scenario = _scenario(obstacles=[{"id": f"o{n}", **box} for n in range(limit + 1)])
    response = shared_client.post("/api/missions", json=scenario)
    assert response.status_code == 422, response.text
    errors = {e["field"]: e["reason"] for e in _strict_json(response.text)["errors"]}
    assert errors["obstacles"] == (f"{limit + 1} obstacles exceed this server's limit of "
                                   f"{limit} (setting max_obstacles)")
