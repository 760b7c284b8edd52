"""Storage faults are told and lose nothing held in memory: a flight whose final write the
store refuses (a full disk) is served from memory with its final status, summary and record,
never `running`, and stored in full once space returns; requests that need a write on a full
disk answer 507 "disk full", never a 500."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from gcs.service.storage_faults import is_disk_full, storage_reason
from tests.api.support import QUICK_CROSSING, example, plan_mission, sse_events
from tests.service.support import fill_the_disk
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(300)


@pytest.mark.flight
def test_a_flight_the_store_refuses_is_held_in_memory_then_stored_in_full(
    mock_settings: Callable[..., Settings], monkeypatch: pytest.MonkeyPatch
) -> None:
    # The refused final write is retried 0.2 s later, then at doubling delays (the
    # service's first delay is 1 s): the same back-off, sooner.
    monkeypatch.setattr("gcs.service.flights.STORE_RETRY_S", 0.2)
    with TestClient(create_app(mock_settings())) as client:
        store = client.app.state.store  # type: ignore[attr-defined]
        real_update = store.update_flight
        disk_full = [True]

        def update(flight_id: str, **values: Any) -> bool:
            if disk_full[0] and values.get("finished"):
                raise OSError(28, "No space left on device")
            return real_update(flight_id, **values)

        monkeypatch.setattr(store, "update_flight", update)
        mission = plan_mission(client, QUICK_CROSSING)
        flight = client.post(f"/api/missions/{mission['id']}/flights",
                                json={"hold_at_goal": 0.5}).json()
        streamed = sse_events(client, flight["links"]["events"])
        assert streamed[-1][0] == "done" and streamed[-1][1]["status"] == "completed"

        # Not stored, and told so: the final state comes from memory, never "running".
        held = client.get(flight["links"]["self"]).json()
        assert held["status"] == "completed" and held["finished_at"] is not None
        assert held["storage"].startswith("disk full") and "No space left" in held["storage"]
        assert held["summary"]["completed"] is True and held["has_record"] is True
        assert held["events"] == [data for kind, data in streamed if kind == "event"]
        listed = client.get("/api/flights").json()["flights"]
        assert [e["status"] for e in listed if e["id"] == flight["id"]] == ["completed"]
        record = client.get(flight["links"]["record"])
        assert record.status_code == 200 and record.json()["summary"]["completed"] is True

        disk_full[0] = False  # space returns: the retry stores everything
        # retries back off to STORE_RETRY_MAX_S
        wait_for(lambda: client.get(flight["links"]["self"]).json()["storage"] is None,
                 "the flight to be stored", timeout=60.0, poll=0.2)
        row = store.get_flight(flight["id"], with_record=True)
        assert row is not None and row.status == "completed" and row.record_json is not None
        assert row.summary == held["summary"] and row.events == held["events"]
        assert client.app.state.fleet.flight(flight["id"]) is None  # type: ignore[attr-defined]


def test_a_write_on_a_full_disk_answers_507_disk_full(
    make_settings: Callable[..., Settings]
) -> None:
    with TestClient(create_app(make_settings()), raise_server_exceptions=False) as client:
        first = client.post("/api/missions?wait=60", json=example("paper-circle2"))
        assert first.status_code == 201
        fill_the_disk(client.app.state.store)  # type: ignore[attr-defined]
        big = {**example("circle16"), "name": "x" * 200}
        answers = [client.post("/api/missions?wait=0", json=big) for _ in range(20)]
        refused = [a for a in answers if a.status_code != 202]
        assert refused, "the capped database took every mission"
        for answer in refused:
            assert answer.status_code == 507, answer.text
            assert answer.json()["reason"].startswith("disk full")
        # What was stored before is still there.
        assert client.get(f"/api/missions/{first.json()['id']}").json()["status"] == "planned"


def test_disk_full_is_recognised_in_each_database_s_words() -> None:
    from sqlalchemy.exc import OperationalError

    sqlite = OperationalError("INSERT ...", {}, Exception("database or disk is full"))
    assert is_disk_full(sqlite) and storage_reason(sqlite).startswith("disk full")
    assert is_disk_full(OSError(28, "No space left on device"))
    locked = OperationalError("INSERT ...", {}, Exception("database is locked"))
    assert not is_disk_full(locked)
    assert storage_reason(locked).startswith("storage unavailable")
