"""The service flies a show that takes off from and lands on its ground grid from the ground:
its mock vehicles stand on the plan's homes, lift off with their wave and land on their slots."""

from __future__ import annotations

import json
from collections.abc import Callable

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.flight.run.executor import TRACKING_TOLERANCE_M
from gcs.phases import EventKind
from gcs.service.settings import Settings
from tests.api.support import QUICK, sse_events
from tests.support.shows import post_sequence as plan_sequence
from tests.support.shows import small_ground_show


@pytest.mark.flight
def test_a_ground_show_is_flown_from_the_ground(mock_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(mock_settings(mock_vehicles=4))) as client:
        mission = plan_sequence(client, small_ground_show())
        assert mission["plan_ok"] is True, mission["error"]
        response = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK)
        assert response.status_code == 201, response.text
        created = response.json()
        events = sse_events(client, created["links"]["events"])
        record = json.loads(client.get(created["links"]["record"]).text)
    assert events[-1][0] == "done"
    summary = record["summary"]
    assert summary["completed"] is True, summary["why"]
    assert summary["min_separation_measured"] >= 1.0 - TRACKING_TOLERANCE_M
    kinds = [(e.get("vehicle"), e["kind"], e["detail"]) for e in record["events"]]
    for vid in ("uav1", "uav2", "uav3", "uav4"):
        assert (vid, EventKind.CLIMB, "lifts off with its wave at t=0.0 s on the plan's "
                                      "setpoints") in kinds
        assert (vid, EventKind.LANDED, "landed and disarmed") in kinds
    assert not [k for k in kinds if k[1] == EventKind.AT_START]  # no climb to a start
