"""A flight's event fan-out: each event goes to the record and to every live subscriber.

`EventFanout.emit` records one event (`FlightRecorder.event`) and hands it to every queue of
`events()`; `close()` ends every subscriber's iteration once the flight is over.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable

from gcs.documents import FlightEvent
from gcs.flight.run.record import FlightRecorder
from gcs.phases import EventKind

__all__ = ["EventFanout"]


class EventFanout:
    """Events of one flight, to its record and its subscribers."""

    def __init__(self, recorder: FlightRecorder, now: Callable[[], float]) -> None:
        self.recorder = recorder
        self.now = now
        """The GCS clock the events are stamped with."""
        self._subscribers: list[asyncio.Queue[FlightEvent | None]] = []
        self._closed = False

    def emit(self, vehicle: str | None, kind: EventKind, detail: str = "") -> None:
        """Record one event and pass it on to every subscriber."""
        event = self.recorder.event(self.now(), vehicle, kind, detail)
        for queue in self._subscribers:
            queue.put_nowait(event)

    async def events(self) -> AsyncIterator[FlightEvent]:
        """Every event from now until the flight ends ({"t", "vehicle", "kind", "detail"})."""
        if self._closed:
            return
        queue: asyncio.Queue[FlightEvent | None] = asyncio.Queue()
        self._subscribers.append(queue)
        try:
            while True:
                event = await queue.get()
                if event is None:
                    return
                yield event
        finally:
            self._subscribers.remove(queue)

    def close(self) -> None:
        """The flight is over: every subscriber's iteration ends."""
        self._closed = True
        for queue in self._subscribers:
            queue.put_nowait(None)
