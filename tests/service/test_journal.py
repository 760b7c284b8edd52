"""Executions stored while they fly (`ExecutionJournal`), and a flight whose final write fails
ends `failed` with the reason instead of staying `running`."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.journal import ExecutionJournal
from gcs.service.settings import Settings
from gcs.service.store import Store
from planner import Scenario
from tests.api.routes.test_missions import plan_mission, sse_events
from tests.api.support import QUICK_CROSSING, example

pytestmark = pytest.mark.timeout(300)


def test_journal_writes_changes_only_and_nothing_after_close(tmp_path: Path) -> None:
    store = Store(f"sqlite:///{tmp_path / 'j.db'}")
    mission = store.create_mission(Scenario.from_dict(example("paper-circle2")).to_dict())
    execution = store.create_execution(mission.id, "mock: a, b")
    writes: list[dict[str, Any]] = []
    real_update = store.update_execution

    def update(execution_id: str, **values: Any) -> bool:
        writes.append(values)
        return real_update(execution_id, **values)

    store.update_execution = update  # type: ignore[method-assign]
    state: dict[str, Any] = {"status": "starting", "events": []}

    async def fly() -> None:
        journal = ExecutionJournal(store, execution.id,
                                   lambda: (state["status"], state["events"], None),
                                   state_period_s=0.02)
        journal.start()
        await asyncio.sleep(0.2)
        state["status"] = "running"
        state["events"].append({"t": 0.1, "vehicle": None, "kind": "armed", "detail": ""})
        await asyncio.sleep(0.2)
        await journal.close()
        state["status"] = "completed"  # after close: must not be written by the journal
        await asyncio.sleep(0.1)

    asyncio.run(fly())
    # One write per distinct state, however many beats passed.
    assert [(w["status"], len(w["events"])) for w in writes] == [("starting", 0), ("running", 1)]
    row = store.get_execution(execution.id)
    assert row is not None and row.status == "running" and row.events == state["events"]
    store.close()


def test_a_flight_the_store_refuses_ends_failed_with_the_reason(
    mock_settings: Callable[..., Settings], monkeypatch: pytest.MonkeyPatch
) -> None:
    with TestClient(create_app(mock_settings())) as client:
        store = client.app.state.store
        real_update = store.update_execution

        def update(execution_id: str, **values: Any) -> bool:
            if values.get("finished") and values.get("record_json") is not None:
                raise OSError(28, "No space left on device")
            return real_update(execution_id, **values)

        monkeypatch.setattr(store, "update_execution", update)
        mission = plan_mission(client, QUICK_CROSSING)
        execution = client.post(f"/api/missions/{mission['id']}/executions",
                                json={"hold_at_goal": 0.5}).json()
        streamed = sse_events(client, execution["links"]["events"])
        done = streamed[-1]
        assert done[0] == "done" and done[1]["status"] == "completed", done[1]
        stored = client.get(execution["links"]["self"]).json()
        assert stored["status"] == "failed"
        assert "could not be stored" in stored["error"]
        assert "No space left on device" in stored["error"]
        assert stored["finished_at"] is not None
        # The flight's events are kept even though its record could not be.
        assert stored["events"] == [data for kind, data in streamed if kind == "event"]
        assert stored["events"]
