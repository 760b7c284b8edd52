"""A replan through the API on the service's mock fleet (real MAVLink over UDP loopback, the
flight in the vehicle process): refusals before, during and after it, its events, its
record, and the plans the flight flew."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from gcs import phases
from gcs.api import create_app
from gcs.api.routes.flights import FlyRequest
from gcs.fleet.fleetfile import POLICIES
from gcs.phases import EventKind
from gcs.service.settings import Settings
from tests.api.support import QUICK, SHORT_CROSSING, example, plan_mission, sse_events
from tests.support.waiting import wait_for

#: Run only with the flight side of in-flight replans (helper flight's branch, wt/flight).
NEEDS_FLIGHT_REPLANS = pytest.mark.skipif(not hasattr(phases, "ReplanStatus"),
                                          reason="needs FlightExecutor.replan (wt/flight)")
pytestmark = NEEDS_FLIGHT_REPLANS
#: The crossing's b to a new goal, d dropped: the rest fly on to theirs.
NEW_GOAL = [1.0, 1.4, 1.5]
#: A lead long enough for the replan to be planned on a busy machine (the flight's bound is
#: what tests/flight checks; here the API is).
LEAD_S = 3.0


def flight_time(client: TestClient, url: str) -> float:
    return float((client.get(url).json()["live"] or {}).get("flight_time") or 0.0)


@pytest.mark.flight
def test_a_replan_through_the_api(mock_settings: Callable[..., Settings]) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, SHORT_CROSSING)
        flown = client.post(f"/api/missions/{mission['id']}/flights",
                            json={**QUICK, "replan_lead_s": LEAD_S})
        assert flown.status_code == 201, flown.text
        flight = flown.json()
        url, links = flight["links"]["self"], flight["links"]
        assert links["replan"].endswith("/replan")
        wait_for(lambda: flight_time(client, url) > 1.0, "the flight clock to pass 1 s", 60)

        # What only the flight can judge crosses from the vehicle process by its field.
        unknown = client.post(links["replan"], json={"goals": {"zz": [1.0, 1.0, 1.0]}})
        assert unknown.status_code == 422 and unknown.json()["field"] == "goals.zz", unknown.text
        outside = client.post(links["replan"], json={"goals": {"b": [9.0, 1.0, 1.0]}})
        assert outside.status_code == 422 and outside.json()["field"] == "goals.b", outside.text
        near = client.post(links["replan"], json={"goals": {"b": [4.5, 3.0, 1.4]}})
        assert near.status_code == 422 and near.json()["field"] == "goals.b", near.text
        # Paused: refused by the service.
        assert client.post(links["pause"]).status_code == 200
        paused = client.post(links["replan"], json={"drop": ["d"]})
        assert paused.status_code == 409, paused.text
        assert "cannot be replanned (status paused)" in paused.json()["reason"]
        assert client.post(links["resume"]).status_code == 200

        answer = client.post(links["replan"], json={"goals": {"b": NEW_GOAL}, "drop": ["d"],
                                                     "drop_action": "land"})
        assert answer.status_code == 202, answer.text
        replan = answer.json()["replan"]
        assert (replan["id"], replan["status"]) == (1, phases.ReplanStatus.PLANNING)
        assert replan["goals"] == {"b": NEW_GOAL} and replan["drop"] == ["d"]
        assert replan["switch_time"] - replan["requested_at"] >= LEAD_S - 0.1
        # One at a time: a second is refused while the first waits for its switch.
        second = client.post(links["replan"], json={"drop": ["c"]})
        assert second.status_code == 409, second.text
        live = client.get(url).json()["live"]
        assert live["replan"]["id"] == 1

        events = sse_events(client, links["events"])
        done = events[-1][1]
        assert done["status"] == "completed", done
        kinds = [data["kind"] for kind, data in events if kind == "event"]
        assert kinds.index(EventKind.REPLAN_STARTED) < kinds.index(EventKind.REPLAN_SWITCHED)
        assert EventKind.REPLAN_MISSED not in kinds
        late = client.post(links["replan"], json={"drop": ["c"]})
        assert late.status_code == 409 and "is not flying" in late.json()["reason"]

        record = json.loads(client.get(links["record"]).content)
        [flown_replan] = record["replans"]
        assert flown_replan["status"] == phases.ReplanStatus.SWITCHED and flown_replan["plan"]
        assert "d" in record["summary"]["dropped"]

        # The plans flown: the mission's, then the replan's from its switch.
        trajectory = client.get(links["trajectory"], params={"rate": 10}).json()
        switch = flown_replan["switch_time"]
        assert trajectory["switches"] == [{"replan": 1, "t": pytest.approx(switch)}]
        assert trajectory["dropped"] == {"d": pytest.approx(switch)}
        by_id = {v["id"]: v for v in trajectory["vehicles"]}
        np.testing.assert_allclose(by_id["b"]["position"][-1], NEW_GOAL, atol=1e-6)
        original = {v["id"]: v["goal"] for v in SHORT_CROSSING["vehicles"]}
        np.testing.assert_allclose(by_id["a"]["position"][-1], original["a"], atol=1e-6)
        t = np.array(trajectory["t"])
        assert t[-1] == pytest.approx(switch + flown_replan["plan"]["scenario"]["steps"]
                                      * flown_replan["plan"]["scenario"]["dt"], abs=1e-6)
        # Completed: every vehicle left on the plan reached its last goal (b its new one).
        assert record["summary"]["completed"] is True
        assert record["summary"]["goal_error_max"] < 0.3


def test_nothing_flying_yet_is_409(mock_settings: Callable[..., Settings]) -> None:
    """A flight still starting (links opening, arming) has no plan flown to replan."""
    with TestClient(create_app(mock_settings())) as client:
        mission = plan_mission(client, copy.deepcopy(SHORT_CROSSING))
        flight = client.post(f"/api/missions/{mission['id']}/flights",
                                json=QUICK).json()
        answer = client.post(flight["links"]["replan"], json={"drop": ["d"]})
        assert answer.status_code == 409, answer.text
        client.post(flight["links"]["abort"], json={"action": "land"})
        events: list[tuple[str, dict[str, Any]]] = sse_events(client, flight["links"]["events"])
        assert events[-1][1]["status"] == "aborted"


@pytest.mark.parametrize(("options", "field", "reason"), [
    ({"replan_lead_s": 50.0}, "replan_lead_s", "less than or equal to 10"),
    ({"replan_lead_s": 0.0}, "replan_lead_s", "greater than 0"),
    ({"policy": "replan_all"}, "policy", "'replan'"),
])
def test_the_replan_fly_options_are_checked(
    client: TestClient, options: dict[str, Any], field: str, reason: str
) -> None:
    store = client.app.state.store  # type: ignore[attr-defined]
    mission = store.create_mission(example("paper-circle2"))
    answer = client.post(f"/api/missions/{mission.id}/flights", json=options)
    assert answer.status_code == 422 and answer.json()["field"] == field, answer.text
    assert reason in answer.json()["reason"], answer.text


def test_the_fly_body_offers_every_policy() -> None:
    """One definition: the Fly body's policies are the fleet file's (`POLICIES`)."""
    policy = FlyRequest.model_json_schema()["properties"]["policy"]["anyOf"][0]
    assert policy["enum"] == list(POLICIES)
