"""One flight while it is under way, in memory: its status, events, live telemetry and the
listeners of its event stream; and the REST document of a flight (stored row + live state)."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from gcs.documents import FlightEvent, FlightSnapshot
from gcs.flight.run.precedence import ABORT_ACTIONS
from gcs.service.events import Broadcast, Event
from gcs.service.remote_flight import RemoteFlight
from gcs.service.statuses import FlightStatus
from gcs.service.store import FlightRow

__all__ = ["LiveFlight", "flight_document"]


@dataclass
class LiveFlight:
    """One flight being flown (in memory while it runs)."""

    id: str
    mission_id: str
    status: FlightStatus = FlightStatus.STARTING
    handle: RemoteFlight | None = None
    """The flight in the vehicle process, once it is made."""
    events: list[FlightEvent] = field(default_factory=list)
    summary: dict[str, Any] | None = None
    error: str | None = None
    aborts: list[str] = field(default_factory=list)
    """The abort actions accepted, in the order they were answered
    (`gcs.flight.run.precedence`); those accepted before the flight existed are passed on to
    it in this order."""
    finished_at: datetime | None = None
    """When the flight ended (its final state is set by then)."""
    unstored: str | None = None
    """Why the ended flight's final state is not stored yet (it is held here and retried);
    None once stored, and while flying."""
    done: asyncio.Event = field(default_factory=asyncio.Event)
    listeners: Broadcast = field(default_factory=Broadcast)

    @property
    def abort_requested(self) -> str | None:
        """The abort action in force, the strongest accepted (None: not aborting); racing
        requests may be answered in another order than the flight took them."""
        return max(self.aborts, key=ABORT_ACTIONS.index, default=None)

    @property
    def active(self) -> bool:
        """The flight has not ended (the vehicles may be flying)."""
        return not self.done.is_set()

    def publish(self, kind: str, data: Mapping[str, Any]) -> None:
        """Tell the stream's listeners."""
        self.listeners.publish(kind, data)

    def set_status(self, status: FlightStatus) -> None:
        """Change the status and tell the listeners."""
        self.status = status
        self.publish("status", {"status": status})

    def snapshot(self) -> FlightSnapshot | None:
        """The flight's live state (phase, vehicles) as the vehicle process last posted it, once
        the flight exists."""
        return None if self.handle is None else self.handle.snapshot()

    def outcome(self) -> dict[str, Any]:
        """The stream's final `done` event."""
        return {"status": self.status, "summary": self.summary, "error": self.error}

    async def stream(self) -> AsyncIterator[Event]:
        """("status"|"event"|"telemetry", data)... then ("done", outcome); events so far
        first, then live."""
        history: list[Event] = [("status", {"status": self.status})]
        history += [("event", event) for event in self.events]
        snapshot = self.snapshot()
        if snapshot is not None:
            history.append(("telemetry", snapshot))
        done = None if self.active else ("done", self.outcome())
        async for event in self.listeners.follow(history, done):
            yield event


def flight_document(row: FlightRow, flight: LiveFlight | None) -> dict[str, Any]:
    """`FlightOut`: the stored flight, with live state while it flies."""
    doc = row.to_dict()
    if flight is not None and flight.active:
        # The live state, and the summary as soon as the flight has one (it is set together
        # with the final status, before the row is stored): never a final status without it.
        doc.update(status=flight.status, events=list(flight.events), live=flight.snapshot())
        if flight.summary is not None:
            doc["summary"] = flight.summary
    elif flight is not None and flight.unstored is not None:
        # Ended, but the store refused its final state: memory holds it, never "running".
        doc.update(status=flight.status, events=list(flight.events), summary=flight.summary,
                   error=flight.error, live=None,
                   has_record=flight.handle is not None and flight.handle.record is not None,
                   finished_at=None if flight.finished_at is None
                   else flight.finished_at.isoformat())
    else:
        doc["live"] = None
    doc["storage"] = None if flight is None else flight.unstored
    doc["links"] = {
        "self": f"/api/flights/{row.id}",
        "events": f"/api/flights/{row.id}/events",
        "abort": f"/api/flights/{row.id}/abort",
        "pause": f"/api/flights/{row.id}/pause",
        "resume": f"/api/flights/{row.id}/resume",
        "replan": f"/api/flights/{row.id}/replan",
        "trajectory": f"/api/flights/{row.id}/trajectory",
        "record": f"/api/flights/{row.id}/record",
        "mission": f"/api/missions/{row.mission_id}",
    }
    return doc
