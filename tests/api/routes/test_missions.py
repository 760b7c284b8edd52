"""Missions through the real app and the real planner: round trip, progress stream, trajectory
export, deletion, and persistence across a restart."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from gcs.service.store import Store
from planner import Plan, Scenario
from tests.api.support import example, plan_mission, sse_events


def test_round_trip_plans_and_reads_back(client: TestClient) -> None:
    scenario = example("paper-circle4")
    response = client.post("/api/missions?wait=60", json=scenario)
    assert response.status_code == 201, response.text
    mission = response.json()
    assert response.headers["location"] == f"/api/missions/{mission['id']}"
    assert mission["status"] == "planned"
    assert mission["vehicle_count"] == 4
    assert mission["scenario"] == Scenario.from_dict(scenario).to_dict()

    plan = mission["plan"]
    assert plan["status"] == "converged"
    assert mission["plan_status"] == "converged" and mission["plan_ok"] is True
    verification = plan["verification"]
    assert verification["separated"] and verification["within_bounds"]
    assert verification["min_separation_continuous"] >= scenario["min_separation"] - 1e-3
    parsed = Plan.from_dict(plan)  # the contract reads back
    assert [v.id for v in parsed.vehicles] == ["uav1", "uav2", "uav3", "uav4"]
    assert parsed.ok

    again = client.get(f"/api/missions/{mission['id']}")
    assert again.status_code == 200
    assert again.json() == mission
    listed = client.get("/api/missions").json()
    assert listed["total"] == 1
    assert listed["missions"][0]["id"] == mission["id"]
    assert "plan" not in listed["missions"][0]

    download = client.get(f"/api/missions/{mission['id']}/plan")
    assert download.status_code == 200
    assert "attachment" in download.headers["content-disposition"]
    assert download.json() == plan


def test_trajectory_is_the_exact_motion_at_the_rate(client: TestClient) -> None:
    mission = plan_mission(client, example("paper-circle4"))
    plan = mission["plan"]
    dt, steps = plan["scenario"]["dt"], plan["scenario"]["steps"]
    response = client.get(f"/api/missions/{mission['id']}/trajectory", params={"rate": 20})
    assert response.status_code == 200
    traj = response.json()
    t = np.array(traj["t"])
    assert traj["frame"] == "world_enu" and traj["rate"] == 20
    assert len(t) == round(steps * dt * 20) + 1
    np.testing.assert_allclose(np.diff(t), 0.05, atol=1e-12)
    per_step = round(dt * 20)
    for vehicle, planned in zip(traj["vehicles"], plan["vehicles"], strict=True):
        assert vehicle["id"] == planned["id"]
        pos = np.array(vehicle["position"])
        vel = np.array(vehicle["velocity"])
        p, v, a = (np.array(planned[k]) for k in ("position", "velocity", "acceleration"))
        # On the step grid the samples are the plan's own states ...
        np.testing.assert_allclose(pos[::per_step], p, atol=1e-9)
        np.testing.assert_allclose(vel[::per_step], v, atol=1e-9)
        # ... and between steps the exact motion under the step's constant acceleration.
        # (Exactly on a step boundary the acceleration may be either neighbour's.)
        k = np.arange(steps)
        acc = np.array(vehicle["acceleration"])
        for j in range(1, per_step):
            s = j / 20
            np.testing.assert_allclose(
                pos[k * per_step + j], p[k] + s * v[k] + 0.5 * s * s * a[k], atol=1e-9
            )
            np.testing.assert_allclose(vel[k * per_step + j], v[k] + s * a[k], atol=1e-9)
            np.testing.assert_allclose(acc[k * per_step + j], a[k], atol=1e-12)
        np.testing.assert_array_equal(acc[-1], 0.0)  # at rest at the end

    csv_response = client.get(
        f"/api/missions/{mission['id']}/trajectory", params={"rate": 20, "format": "csv"}
    )
    assert csv_response.status_code == 200
    assert csv_response.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(csv_response.text)))
    assert len(rows) == 4 * len(t)  # one row per vehicle and time
    assert list(rows[0]) == ["vehicle", "t", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az"]
    by_vehicle = {v["id"]: v for v in traj["vehicles"]}
    for index, row in enumerate(rows):
        vehicle = by_vehicle[row["vehicle"]]
        i = index % len(t)
        assert float(row["t"]) == pytest.approx(t[i], abs=1e-6)
        got = [float(row[c]) for c in ("x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")]
        want = vehicle["position"][i] + vehicle["velocity"][i] + vehicle["acceleration"][i]
        np.testing.assert_allclose(got, want, atol=1e-6)


def test_progress_stream_reports_every_iteration(client: TestClient) -> None:
    # the whole fleet alone: auto's race would also stream the losing method's iterations
    response = client.post("/api/missions?wait=0",
                           json=example("paper-circle6") | {"method": "whole"})
    assert response.status_code == 202, response.text
    mission = response.json()
    assert mission["status"] == "planning" and mission["plan"] is None
    events = sse_events(client, mission["links"]["events"])
    kinds = [kind for kind, _ in events]
    assert kinds[-1] == "done" and kinds.count("done") == 1
    done = events[-1][1]
    assert done["status"] == "planned"
    iterations = [data for kind, data in events if kind == "iteration"]
    assert [r["iteration"] for r in iterations] == list(range(len(iterations)))
    planned = client.get(f"/api/missions/{mission['id']}").json()
    assert planned["status"] == "planned" and planned["progress"] == []
    recorded = planned["plan"]["iterations"]
    assert [r["iteration"] for r in recorded] == [r["iteration"] for r in iterations]
    assert [r["cost"] for r in recorded] == pytest.approx([r["cost"] for r in iterations])
    # A finished mission's stream is just its outcome.
    assert sse_events(client, mission["links"]["events"]) == [("done", done)]


def test_list_is_newest_first_and_paged(client: TestClient) -> None:
    ids = [plan_mission(client, example("paper-circle2") | {"name": f"m{i}"})["id"]
           for i in range(3)]
    page = client.get("/api/missions", params={"limit": 2}).json()
    assert page["total"] == 3 and page["limit"] == 2
    assert [m["id"] for m in page["missions"]] == ids[::-1][:2]
    rest = client.get("/api/missions", params={"limit": 2, "offset": 2}).json()
    assert [m["id"] for m in rest["missions"]] == [ids[0]]
    assert rest["missions"][0]["name"] == "m0"


def test_delete_removes_everything(client: TestClient) -> None:
    mission = plan_mission(client, example("paper-circle2"))
    url = f"/api/missions/{mission['id']}"
    assert client.get(f"{url}/trajectory").status_code == 200  # now cached
    assert client.delete(url).status_code == 204
    for path in ("", "/trajectory", "/plan", "/events"):
        response = client.get(f"{url}{path}")
        assert response.status_code == 404
        assert response.json()["field"] == "mission_id"
    assert client.delete(url).status_code == 404
    assert client.get("/api/missions").json()["total"] == 0


def test_restart_keeps_missions_and_plans(make_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(make_settings())) as first:
        mission = plan_mission(first, example("paper-circle4"))
        before = first.get(f"/api/missions/{mission['id']}/trajectory?format=csv").text
    with TestClient(create_app(make_settings())) as second:
        again = second.get(f"/api/missions/{mission['id']}")
        assert again.status_code == 200
        assert again.json() == mission
        assert second.get("/api/missions").json()["total"] == 1
        assert second.get(f"/api/missions/{mission['id']}/trajectory?format=csv").text == before


def test_stopping_while_planning_marks_the_mission_failed(
    make_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(make_settings())) as first:
        response = first.post("/api/missions?wait=0", json=example("random64"))
        assert response.status_code == 202
        mission_id = response.json()["id"]
    with TestClient(create_app(make_settings())) as second:
        mission = second.get(f"/api/missions/{mission_id}").json()
        assert mission["status"] == "failed"
        assert "stopped" in mission["error"]["reason"]
        response = second.get(f"/api/missions/{mission_id}/trajectory")
        assert response.status_code == 409
        assert response.json()["field"] == "mission_id"
        assert "no plan" in response.json()["reason"]


def test_a_killed_server_leaves_no_mission_planning_forever(
    make_settings: Callable[..., Settings],
) -> None:
    settings = make_settings()
    # What a killed process leaves behind: a row still `planning`, no worker for it.
    store = Store(settings.database_url)
    row = store.create_mission(Scenario.from_dict(example("paper-circle2")).to_dict())
    store.close()
    with TestClient(create_app(settings)) as client:
        mission = client.get(f"/api/missions/{row.id}").json()
        assert mission["status"] == "failed"
        assert mission["error"]["reason"] == "the service stopped before this plan finished"
        assert client.delete(f"/api/missions/{row.id}").status_code == 204
