"""Executions stored while they fly (`FlightJournal`). A flight whose final write fails
is tests/service/test_storage_faults.py's."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest

from gcs.service.journal import FlightJournal
from gcs.service.store import Store
from planner import Scenario
from tests.api.support import example
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(300)


def test_journal_writes_changes_only_and_nothing_after_close(tmp_path: Path) -> None:
    store = Store(f"sqlite:///{tmp_path / 'j.db'}")
    mission = store.create_mission(Scenario.from_dict(example("paper-circle2")).to_dict())
    flight = store.create_flight(mission.id, "mock: a, b")
    writes: list[dict[str, Any]] = []
    real_update = store.update_flight

    def update(flight_id: str, **values: Any) -> bool:
        writes.append(values)
        return real_update(flight_id, **values)

    store.update_flight = update  # type: ignore[method-assign]
    state: dict[str, Any] = {"status": "starting", "events": []}

    async def fly() -> None:
        journal = FlightJournal(store, flight.id,
                                   lambda: (state["status"], state["events"], None),
                                   state_period_s=0.02)
        journal.start()
        await until(lambda: len(writes) >= 1, "the journal to write")
        await asyncio.sleep(0.1)  # more beats of the same state: nothing more is written
        state["status"] = "running"
        state["events"].append({"t": 0.1, "vehicle": None, "kind": "armed", "detail": ""})
        await until(lambda: len(writes) >= 2, "the journal to write")
        await asyncio.sleep(0.1)
        await journal.close()
        state["status"] = "completed"  # after close: must not be written by the journal
        await asyncio.sleep(0.1)

    asyncio.run(fly())
    # One write per distinct state, however many beats passed.
    assert [(w["status"], len(w["events"])) for w in writes] == [("starting", 0), ("running", 1)]
    row = store.get_flight(flight.id)
    assert row is not None and row.status == "running" and row.events == state["events"]
    store.close()
