"""REST details a client relies on: every validation error at once, a correct Allow on 405,
resumable event streams (`id:` lines, Last-Event-ID), paginated flights without their events,
and a CSV without negative zeros."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import QUICK, QUICK_CROSSING, example


def sse(client: TestClient, url: str, headers: dict[str, str] | None = None
        ) -> list[tuple[str, str | None, dict[str, Any]]]:
    """Every (event, id, data) of a server-sent event stream, until the server ends it."""
    events: list[tuple[str, str | None, dict[str, Any]]] = []
    fields: dict[str, str] = {}
    with client.stream("GET", url, headers=headers or {}) as response:
        assert response.status_code == 200
        for line in [*response.iter_lines(), ""]:
            if not line:  # a blank line ends an event
                if "data" in fields:
                    events.append((fields.get("event", "message"), fields.get("id"),
                                   json.loads(fields["data"])))
                fields = {}
            elif not line.startswith(":"):
                name, _, value = line.partition(":")
                fields[name] = value.removeprefix(" ")
    return events


def test_every_query_error_is_reported_at_once(shared_client: TestClient) -> None:
    response = shared_client.get("/api/missions", params={"limit": 0, "offset": -1})
    assert response.status_code == 422
    assert {e["field"] for e in response.json()["errors"]} == {"limit", "offset"}


def test_405_names_the_allowed_methods(shared_client: TestClient) -> None:
    cases = {("PUT", "/api/missions"): "GET, POST", ("POST", "/api/status"): "GET",
             ("PATCH", "/api/missions/abc"): "DELETE, GET",
             ("GET", "/api/flights/abc/abort"): "POST"}
    for (method, path), allow in cases.items():
        response = shared_client.request(method, path)
        assert response.status_code == 405, (method, path)
        assert response.headers["allow"] == allow, (method, path)
        assert response.json()["reason"] == "Method Not Allowed"


def test_planning_events_have_ids_and_resume_after_last_event_id(
    make_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(make_settings())) as client:
        mission = client.post("/api/missions?wait=0", json=example("random16")).json()
        url = f"/api/missions/{mission['id']}/events"
        everything = sse(client, url)
        iterations = [(event_id, data) for kind, event_id, data in everything
                      if kind == "iteration"]
        assert [event_id for event_id, _ in iterations] == [
            str(n) for n in range(len(iterations))]
        assert everything[-1][0] == "done" and len(iterations) >= 2
    # A reconnecting client gets what came after its last id (here, on a slower plan so it
    # is still planning when the second stream opens).
    with TestClient(create_app(make_settings())) as client:
        mission = client.post("/api/missions?wait=0", json=example("random64")).json()
        url = f"/api/missions/{mission['id']}/events"
        resumed = sse(client, url, {"Last-Event-ID": "1"})
        full = sse(client, url)  # the same job, once it has ended
        ids = [event_id for kind, event_id, _ in resumed if kind == "iteration"]
        assert ids and ids[0] == "2" and ids == [str(n) for n in range(2, 2 + len(ids))]
        assert resumed[-1][0] == "done" and resumed[-1][2]["status"] == "planned"
        assert full == [("done", None, resumed[-1][2])]


@pytest.mark.flight
def test_flight_events_resume_and_flights_are_paginated_without_events(
    mock_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(mock_settings())) as client:
        mission = client.post("/api/missions?wait=60", json=QUICK_CROSSING).json()
        flight = client.post(f"/api/missions/{mission['id']}/flights",
                             json=QUICK).json()
        live = sse(client, flight["links"]["events"])
        assert live[-1][0] == "done" and live[-1][2]["status"] == "completed"
        recorded = [(event_id, data) for kind, event_id, data in live if kind == "event"]
        assert [i for i, _ in recorded] == [str(n) for n in range(len(recorded))]
        assert all(event_id is None for kind, event_id, _ in live if kind != "event")
        # Reconnecting after event k: the status, then only the events after k, then done.
        k = len(recorded) // 2
        again = sse(client, flight["links"]["events"], {"Last-Event-ID": str(k)})
        assert again[0][0] == "status" and again[-1][0] == "done"
        assert [(i, d) for kind, i, d in again if kind == "event"] == recorded[k + 1:]

        page = client.get("/api/flights", params={"limit": 1}).json()
        assert (page["total"], page["limit"], page["offset"]) == (1, 1, 0)
        listed = page["flights"][0]
        assert listed["id"] == flight["id"] and "events" not in listed
        assert listed["event_count"] == len(recorded)
        assert client.get("/api/flights", params={"offset": 1}).json()["flights"] == []
        assert len(client.get(flight["links"]["self"]).json()["events"]) == len(recorded)


def test_csv_has_no_negative_zero(shared_client: TestClient) -> None:
    mission = shared_client.post("/api/missions?wait=60", json=example("paper-circle2")).json()
    url = f"/api/missions/{mission['id']}/trajectory"
    text = shared_client.get(url, params={"format": "csv"}).text
    assert "-0.000000" not in text
    rows = list(csv.reader(io.StringIO(text)))[1:]
    exported = shared_client.get(url).json()
    first = exported["vehicles"][0]
    for row, position in zip(rows, first["position"], strict=False):
        assert [float(v) for v in row[2:5]] == [round(p, 6) + 0.0 for p in position]
