"""Admission to the planning queue is atomic: concurrent POSTs beyond `plan_queue_max` are
answered 503 and store nothing, no mission is left `planning` without a job, and a stale
`planning` row that no job holds can still be cancelled (it becomes `failed`) or deleted."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from planner import Scenario
from tests.api.support import example

pytestmark = pytest.mark.timeout(240)

QUEUE_MAX = 3
POSTS = 12


def _slow_store_writes(client: TestClient) -> list[str]:
    """Widen the window between the capacity check and the stored row, as a loaded database
    would: every mission write takes a little longer. Returns the ids written."""
    store = client.app.state.store  # type: ignore[attr-defined]
    real = store.create_mission
    written: list[str] = []
    lock = threading.Lock()

    def create(*args: Any, **kwargs: Any) -> Any:
        time.sleep(0.05)  # the race window, not a wait for something
        row = real(*args, **kwargs)
        with lock:
            written.append(row.id)
        return row

    store.create_mission = create
    return written


def test_concurrent_posts_past_the_queue_limit_store_nothing(
    make_settings: Callable[..., Settings],
) -> None:
    body = example("paper-circle8")
    with TestClient(create_app(make_settings(plan_queue_max=QUEUE_MAX))) as client:
        written = _slow_store_writes(client)
        start = threading.Barrier(POSTS)

        def post(_: int) -> Any:
            start.wait(timeout=30)
            return client.post("/api/missions?wait=0", json=body)

        with ThreadPoolExecutor(POSTS) as pool:
            answers = list(pool.map(post, range(POSTS)))

        codes = sorted(a.status_code for a in answers)
        accepted = [a.json()["id"] for a in answers if a.status_code in (201, 202)]
        refused = [a for a in answers if a.status_code == 503]
        assert set(codes) <= {201, 202, 503}, codes
        assert refused, "every post was admitted: the queue limit was not in force"
        assert all(a.json()["field"] == "planning" for a in refused)
        # A refused request stores nothing: exactly the admitted missions exist.
        listed = client.get("/api/missions?limit=500").json()
        assert listed["total"] == len(accepted)
        assert sorted(m["id"] for m in listed["missions"]) == sorted(accepted)
        assert sorted(written) == sorted(accepted)
        # Every admitted mission is held by a job, and each ends planned.
        planning = client.app.state.planning  # type: ignore[attr-defined]
        for mission_id in accepted:
            assert planning.job(mission_id) is not None
        for mission_id in accepted:
            done = client.get(f"/api/missions/{mission_id}/events")
            assert "event: done" in done.text
            assert client.get(f"/api/missions/{mission_id}").json()["status"] == "planned"
        # The queue is free again: the next post is admitted.
        assert client.post("/api/missions?wait=0", json=body).status_code in (201, 202)


def test_a_stale_planning_mission_can_be_cancelled_and_deleted(client: TestClient) -> None:
    store = client.app.state.store  # type: ignore[attr-defined]
    scenario = Scenario.from_dict(example("paper-circle2")).to_dict()
    # Rows left `planning` with no job (as a store that refused the final write leaves them).
    stale, other = store.create_mission(scenario), store.create_mission(scenario)

    cancelled = client.post(f"/api/missions/{stale.id}/cancel")
    assert cancelled.status_code == 200, cancelled.text
    assert cancelled.json()["status"] == "failed"
    assert "no plan job" in cancelled.json()["error"]["reason"]
    assert client.post(f"/api/missions/{stale.id}/cancel").status_code == 409  # not planning

    assert client.delete(f"/api/missions/{other.id}").status_code == 204
    assert client.get(f"/api/missions/{other.id}").status_code == 404
    assert client.delete(f"/api/missions/{stale.id}").status_code == 204
