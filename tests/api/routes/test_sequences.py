"""Formation sequences through POST /api/missions: planned as one mission (legs as Dask
tasks), its stitched plan flyable, exports (trajectory CSV, show-tool CSV per vehicle), work
bounds and field-named errors before anything is stored, and a flight on the mock fleet."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from planner import Plan
from tests.api.support import GOALS, OUT_AND_BACK, QUICK, STARTS, sse_events
from tests.support.shows import post_sequence as plan_sequence
from tests.support.waiting import wait_for


def test_a_sequence_is_a_mission_with_a_stitched_flyable_plan(client: TestClient) -> None:
    mission = plan_sequence(client, OUT_AND_BACK)
    assert mission["status"] == "planned" and mission["plan_ok"] is True, mission["error"]
    # The mission's scenario is the whole timeline: starts on F0, ends on the last formation.
    scenario = mission["scenario"]
    assert scenario["steps"] == 66 and scenario["dt"] == 0.2
    assert [v["start"] for v in scenario["vehicles"]] == STARTS
    assert [v["goal"] for v in scenario["vehicles"]] == STARTS
    plan = Plan.from_dict(client.get(mission["links"]["plan"]).json())
    assert plan.ok and plan.sequence is not None
    assert [f["name"] for f in plan.sequence["formations"]] == ["home", "crossed", "home"]
    assert [s["kind"] for s in plan.sequence["timeline"]] == ["hold", "leg", "hold", "leg",
                                                             "hold"]
    assert [leg["status"] for leg in plan.sequence["legs"]] == ["converged"] * 2
    # At rest on the middle formation during its hold (t = 6.4 .. 6.8 s).
    p = plan.positions()
    np.testing.assert_allclose(p[:, 32:35], np.repeat(np.array(GOALS)[:, None], 3, 1),
                               atol=1e-9)
    assert sse_events(client, mission["links"]["events"])[-1][0] == "done"

    csv = client.get(f"/api/missions/{mission['id']}/trajectory?rate=5&format=csv")
    assert csv.status_code == 200
    assert len(csv.text.strip().splitlines()) == 1 + 4 * (66 + 1)  # 13.2 s at 5 Hz, 4 vehicles

    show = client.get(f"/api/missions/{mission['id']}/trajectory",
                      params={"format": "show-csv", "vehicle": "c", "rate": 5})
    assert show.status_code == 200, show.text
    assert show.headers["content-type"].startswith("text/csv")
    rows = show.text.strip().splitlines()
    assert rows[0] == "Time [msec],x [m],y [m],z [m]"
    assert len(rows) == 1 + 67
    assert rows[1] == "0,2.9000,1.0000,1.3000"
    assert rows[-1].startswith("13200,")
    t, x, y, z = (float(c) for c in rows[34].split(","))  # t = 6.6 s: on the crossed point
    assert t == 6600
    np.testing.assert_allclose([x, y, z], GOALS[2], atol=1e-4)


@pytest.fixture(scope="module")
def shared_sequence(shared_client: TestClient) -> dict[str, Any]:
    """OUT_AND_BACK planned once on the module's app."""
    return plan_sequence(shared_client, OUT_AND_BACK)


@pytest.mark.parametrize(
    ("params", "field"),
    [({"format": "show-csv"}, "vehicle"), ({"format": "show-csv", "vehicle": "zz"}, "vehicle")],
)
def test_show_csv_refusals_name_the_field(shared_client: TestClient,
                                          shared_sequence: dict[str, Any],
                                          params: dict[str, str], field: str) -> None:
    mission = shared_sequence
    response = shared_client.get(f"/api/missions/{mission['id']}/trajectory", params=params)
    assert response.status_code == 422
    assert response.json()["field"] == field


def _changed(change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    body = copy.deepcopy(OUT_AND_BACK)
    change(body)
    return body


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (lambda b: b["formations"][1].update(duration=1000), "formations", "max_horizon_s"),
        (lambda b: b["formations"][2].update(duration=80), "formations", "max_steps"),
        (lambda b: b.update(formations=[b["formations"][0]] + [b["formations"][1]] * 21),
         "formations", "legs"),
        (lambda b: b["formations"][1]["positions"][2].__setitem__(0, 1e9),
         "formations[1].positions[2][0]", "max_coordinate_m"),
        (lambda b: b["formations"][1].pop("duration"), "formations[1].duration", "required"),
        (lambda b: b["formations"][2].update(duration=0.6), "formations[2].duration",
         "too short"),
        (lambda b: b["formations"][1]["positions"].__setitem__(1, GOALS[0]),
         "formations[1].positions[1]", ""),
    ],
)
def test_bad_sequences_are_422_naming_the_field_and_nothing_is_stored(
    shared_client: TestClient, change: Callable[[dict[str, Any]], None], field: str, words: str
) -> None:
    before = shared_client.get("/api/missions").json()["total"]
    response = shared_client.post("/api/missions?wait=10", json=_changed(change))
    assert response.status_code == 422, response.text
    body = response.json()
    fields = [e["field"] for e in body.get("errors", [])] or [body["field"]]
    assert field in fields, body
    assert words in response.text
    assert shared_client.get("/api/missions").json()["total"] == before


def test_too_many_vehicles_is_refused_before_parsing(shared_client: TestClient) -> None:
    body = _changed(lambda b: b.update(vehicles=[f"v{n}" for n in range(17)]))
    response = shared_client.post("/api/missions", json=body)
    assert response.status_code == 422
    assert response.json()["field"] == "vehicles" and "max_vehicles" in response.text


@pytest.mark.flight
def test_a_planned_sequence_flies_on_the_mock_fleet(mock_settings: Callable[..., Settings]
                                                    ) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_sequence(client, OUT_AND_BACK)
        assert mission["plan_ok"] is True
        response = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK)
        assert response.status_code == 201, response.text
        flight = response.json()
        events = sse_events(client, flight["links"]["events"])
        done = events[-1][1]
        assert done["status"] == "completed", done
        assert done["summary"]["goal_error_max"] < 0.2
        assert done["summary"]["min_separation_measured"] > 1.0 - 0.1
        wait_for(lambda: client.get(f"/api/missions/{mission['id']}/flights").json(),
                 "the flight record", 5)


#: OUT_AND_BACK lit: red at home, fading to blue on the way out, through black to green back.
LIT: dict[str, Any] = {**OUT_AND_BACK, "formations": [
    {**OUT_AND_BACK["formations"][0], "color": "#ff0000"},
    {**OUT_AND_BACK["formations"][1], "color": "#0000ff", "lights": "fade"},
    {**OUT_AND_BACK["formations"][2], "color": [0, 255, 0], "lights": "black"},
]}


def test_a_lit_sequence_s_trajectory_carries_each_drone_s_light_changes(
        shared_client: TestClient, shared_sequence: dict[str, Any]) -> None:
    mission = plan_sequence(shared_client, LIT)
    trajectory = shared_client.get(f"/api/missions/{mission['id']}/trajectory?rate=5").json()
    # Legs 0.4-6.4 s (out) and 6.8-12.8 s (back, through black at its middle).
    expected = [[0.0, 0.0, "#ff0000"], [0.4, 6.4, "#0000ff"], [6.8, 9.8, "#000000"],
                [9.8, 12.8, "#00ff00"]]
    for vehicle in trajectory["vehicles"]:
        assert [[pytest.approx(a), pytest.approx(b), c] for a, b, c in vehicle["lights"]] \
            == expected, vehicle["id"]
    dark = shared_client.get(f"/api/missions/{shared_sequence['id']}/trajectory?rate=5").json()
    assert all("lights" not in v for v in dark["vehicles"])
