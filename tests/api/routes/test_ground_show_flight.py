"""The service refuses to fly a show that takes off from and lands on the ground: 409 naming
the mission and the fix, before any vehicle is armed."""

from __future__ import annotations

from collections.abc import Callable

from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.support.shows import ground_show as _show
from tests.support.shows import post_sequence as plan_sequence


def test_a_ground_show_is_not_flown(mock_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(mock_settings(mock_vehicles=9))) as client:
        mission = plan_sequence(client, _show(landing={}))
        assert mission["plan_ok"] is True, mission["error"]
        response = client.post(f"/api/missions/{mission['id']}/flights")
        assert response.status_code == 409, response.text
        body = response.json()
        assert body["field"] == "mission_id"
        assert "takes off from and lands on the ground" in body["reason"]
        assert "fleetplan export PLAN.json --format skyc" in body["reason"]
        assert client.get("/api/flights").json()["total"] == 0  # nothing was started
