"""Fan-out of a job's events (a plan's iterations, a flight's events) to every listener.

Each listener gets its own queue. `follow` yields what happened so far first, then live
events until a "done" one; taking the history and subscribing happen in the same event-loop
step, so no event can fall between them.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Iterable
from typing import Any

__all__ = ["Broadcast", "Event"]

#: (kind, data): kind "done" ends a stream.
Event = tuple[str, dict[str, Any]]


class Broadcast:
    """Publish events to any number of `follow` iterators."""

    def __init__(self) -> None:
        self._queues: set[asyncio.Queue[Event]] = set()

    def publish(self, kind: str, data: dict[str, Any]) -> None:
        for queue in self._queues:
            queue.put_nowait((kind, data))

    async def follow(self, history: Iterable[Event], done: Event | None
                     ) -> AsyncIterator[Event]:
        """`history`, then `done` if the job already ended, else live events up to "done".

        Call it in the same step as the history is taken (no await in between)."""
        queue: asyncio.Queue[Event] = asyncio.Queue()
        self._queues.add(queue)
        try:
            for event in history:
                yield event
            if done is not None:
                yield done
                return
            while True:
                event = await queue.get()
                yield event
                if event[0] == "done":
                    return
        finally:
            self._queues.discard(queue)
