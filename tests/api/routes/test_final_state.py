"""A flight's stream ends with the fleet as it is: the last telemetry before `done` shows
every vehicle landed and disarmed, so a page following the stream never keeps a vehicle
"armed / landing" after it disarmed."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import QUICK, QUICK_CROSSING, plan_mission, sse_events


@pytest.mark.flight
def test_the_last_telemetry_before_done_shows_the_fleet_landed_and_disarmed(
    mock_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, QUICK_CROSSING)
        flight = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK)
        assert flight.status_code == 201, flight.text
        events = sse_events(client, flight.json()["links"]["events"])
    kinds = [kind for kind, _ in events]
    assert kinds[-1] == "done" and events[-1][1]["status"] == "completed", events[-1]
    landed = {data["vehicle"] for kind, data in events
              if kind == "event" and data.get("kind") == "landed"}
    assert landed == {v["id"] for v in QUICK_CROSSING["vehicles"]}
    last = max(i for i, kind in enumerate(kinds) if kind == "telemetry")
    # no event after the last telemetry leaves the page's table behind it
    assert "event" not in kinds[last:], kinds[last:]
    final = events[last][1]
    assert [(v["id"], v["armed"], v["phase"]) for v in final["vehicles"]] == [
        (v["id"], False, "landed") for v in QUICK_CROSSING["vehicles"]]
