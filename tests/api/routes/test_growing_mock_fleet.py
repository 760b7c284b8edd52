"""A mock fleet that grows (`serve --mock auto`, the default): a plan with more vehicles than
the mocks started flies on as many mocks as it has, and one over `mock_max_vehicles` is
refused naming the setting."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import QUICK, example, plan_mission, refused, sse_events

#: The paper's 6-vehicle circle swap in 8 s: two vehicles more than the 4 mocks started.
SIX: dict[str, Any] = example("paper-circle6") | {"name": "circle6-quick", "steps": 40}


@pytest.mark.flight
def test_a_plan_larger_than_the_fleet_flies_on_mocks_added_for_it(
    mock_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(mock_settings(mock_max_vehicles=8))) as client:
        fleet = client.get("/api/vehicles").json()["fleet"]
        assert (fleet["vehicles"], fleet["grows_to"]) == (4, 8)
        mission = plan_mission(client, SIX)
        assert mission["status"] == "planned" and mission["plan_ok"], mission
        response = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK)
        assert response.status_code == 201, response.text
        flight = response.json()
        done = sse_events(client, flight["links"]["events"])[-1]
        assert done[0] == "done" and done[1]["status"] == "completed", done
        record = client.get(flight["links"]["record"]).json()
        assert sorted(v["id"] for v in record["vehicles"]) == [f"uav{i}" for i in range(1, 7)]
        after = client.get("/api/vehicles").json()
        assert after["fleet"]["vehicles"] == 6 and len(after["vehicles"]) == 6


def test_a_plan_over_the_growth_limit_is_refused_naming_the_setting(
    mock_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(mock_settings(mock_max_vehicles=5))) as client:
        mission = plan_mission(client, SIX)
        refused(client.post(f"/api/missions/{mission['id']}/flights"), 409, "fleet",
                "the plan has 6 vehicles, more than the mock fleet may grow to: 5 (setting "
                "mock_max_vehicles): restart the service with FLEETPLAN_MOCK_MAX_VEHICLES=6")
        assert client.get("/api/vehicles").json()["fleet"]["vehicles"] == 4  # none added
