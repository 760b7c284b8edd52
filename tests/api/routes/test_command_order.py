"""Conflicting commands raced through the REST API on the mock fleet: land, hold, pause and
replan sent at the same instant resolve by the documented precedence (land overrides hold and
pause, an abort overrides replan); the loser is refused with 409 and the reason, or applied
after the winner; nothing accepted goes without its event."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import QUICK, SHORT_CROSSING, plan_mission, sse_events
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(180)

#: The racing requests: (link, body).
RACE: list[tuple[str, dict[str, Any] | None]] = [
    ("abort", {"action": "hold"}), ("abort", {"action": "land"}), ("pause", None),
    ("replan", {"drop": ["d"]})]


@pytest.mark.flight
def test_racing_commands_resolve_by_precedence(mock_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, SHORT_CROSSING)
        flight = client.post(f"/api/missions/{mission['id']}/flights", json=QUICK).json()
        links = flight["links"]
        wait_for(lambda: (client.get(links["self"]).json()["live"] or {}).get("phase")
                 == "flying", "the flight clock", 30)
        start = threading.Barrier(len(RACE))

        def send(link: str, body: dict[str, Any] | None) -> tuple[int, dict[str, Any]]:
            start.wait()
            response = client.post(links[link], json=body)
            return response.status_code, response.json()

        with ThreadPoolExecutor(len(RACE)) as pool:
            answers = list(pool.map(lambda request: send(*request), RACE))
        (hold, hold_body), (land, _), (pause, pause_body), (replan, replan_body) = answers

        # land wins whatever came first; the hold is applied before it, or refused
        assert land == 202
        assert hold == 202 or (hold == 409 and hold_body["reason"].endswith(
            "land overrides hold")), hold_body
        assert pause in (200, 409), pause_body
        assert replan in (202, 409), replan_body
        if replan == 409:
            assert "abort" in replan_body["reason"] or "paused" in replan_body["reason"]
        # after the race, nothing but a land may follow the abort
        late_hold = client.post(links["abort"], json={"action": "hold"})
        assert late_hold.status_code in (409,), late_hold.text
        assert client.post(links["pause"]).status_code == 409
        assert "an abort overrides replan" in client.post(
            links["replan"], json={"drop": ["c"]}).json()["reason"]

        done = sse_events(client, links["events"])[-1]
        assert done[0] == "done" and done[1]["status"] == "aborted"
        events = client.get(links["self"]).json()["events"]
        details = [e["detail"] for e in events if e["kind"] == "abort"]
        # one event per accepted abort, in the order the flight took them
        accepted = ["land"] + (["hold"] if hold == 202 else [])
        assert sorted(d.split(": ")[1].split(" ")[0] for d in details) == sorted(accepted)
        if hold == 202 and details[0].startswith("operator abort: hold all"):
            assert "overrides the hold" in details[1]
        refused = [e["detail"] for e in events if e["kind"] == "command_refused"]
        assert len(refused) == (hold == 409) + 1  # the race's hold, if refused, and the late
        kinds = {e["kind"] for e in events}
        if pause == 200:
            assert "pause" in kinds
        if replan == 202:
            assert {"replan_started", "replan_missed"} <= kinds
        wait_for(lambda: all(v["armed"] is False and v["position"][2] < 0.1
                             for v in client.get("/api/vehicles").json()["vehicles"]),
                 "every vehicle landed and disarmed", 20)
