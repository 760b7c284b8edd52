"""Planning jobs through the REST API (embedded Dask cluster of 2 workers): cancel, DELETE while
planning, a per-request time limit, and 503 when the queue is full."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import example
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(300)


@pytest.fixture
def jobs_client(make_settings: Callable[..., Settings]) -> Iterator[TestClient]:
    settings = make_settings(plan_workers=2, plan_queue_max=2, plan_time_limit_s=120)
    with TestClient(create_app(settings)) as client:
        yield client


def test_cancel_fails_the_mission_and_frees_the_queue(jobs_client: TestClient) -> None:
    client = jobs_client
    # Plans that outlast the test, with SCP iterations short enough to stop at the next.
    first = client.post("/api/missions?wait=0", json=example("random64"))
    second = client.post("/api/missions?wait=0", json=example("random64"))
    assert first.status_code == second.status_code == 202
    full = client.post("/api/missions?wait=0", json=example("paper-circle2"))
    assert full.status_code == 503
    assert full.json()["field"] == "planning" and "plan_queue_max" in full.json()["reason"]
    assert client.get("/api/missions").json()["total"] == 2  # nothing stored for it

    cancelled = client.post(f"/api/missions/{first.json()['id']}/cancel")
    assert cancelled.status_code == 200, cancelled.text
    body = cancelled.json()
    assert body["status"] == "failed"
    assert body["error"] == {"field": None, "reason": "cancelled by the operator"}
    assert client.post(f"/api/missions/{first.json()['id']}/cancel").status_code == 409

    # DELETE while planning cancels, then deletes.
    assert client.delete(f"/api/missions/{second.json()['id']}").status_code == 204
    assert client.get(f"/api/missions/{second.json()['id']}").status_code == 404
    assert client.get("/api/status").json()["planning_jobs"] == 0
    again = client.post("/api/missions?wait=60", json=example("paper-circle2"))
    assert again.status_code == 201 and again.json()["status"] == "planned"


def test_time_limit_per_request(jobs_client: TestClient) -> None:
    client = jobs_client
    response = client.post("/api/missions?wait=120&time_limit=0.05", json=example("random128"))
    assert response.status_code == 201, response.text
    assert response.json()["status"] == "failed"
    assert response.json()["error"]["reason"] == "planning exceeded its time limit of 0.05 s"
    too_long = client.post("/api/missions?time_limit=121", json=example("paper-circle2"))
    assert too_long.status_code == 422
    assert too_long.json()["field"] == "time_limit"
    assert "at most 120 s" in too_long.json()["reason"]


def test_a_mission_planning_reports_its_progress_and_can_be_cancelled(
        jobs_client: TestClient) -> None:
    """GET /api/missions/{id} while planning: `planning` sums up the progress (the records so
    far, the last one, the elapsed time); cancel stops it. random128 as a whole fleet plans
    for seconds, iteration by iteration."""
    client = jobs_client
    mission = client.post("/api/missions?wait=0",
                          json=example("random128") | {"method": "whole"}).json()

    def recorded() -> dict | None:
        """The mission once it has a record of progress (still planning)."""
        got = client.get(f"/api/missions/{mission['id']}").json()
        assert got["status"] == "planning", "planned before a record was seen"
        return got if got["planning"]["iterations"] >= 1 else None

    doc = wait_for(recorded, "the first record of progress", timeout=120.0)
    summary = doc["planning"]
    assert summary["last"] == doc["progress"][summary["iterations"] - 1]
    assert summary["last"]["method"] == "whole" and summary["batches"] is None
    assert summary["elapsed_s"] > 0
    cancelled = client.post(f"/api/missions/{mission['id']}/cancel").json()
    assert cancelled["status"] == "failed" and cancelled["planning"] is None
