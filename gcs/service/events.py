"""Fan-out of a job's events (a plan's iterations, a flight's events) to every listener.

Each listener gets its own queue. `follow` yields what happened so far first, then live
events until a "done" one; taking the history and subscribing happen in the same event-loop
step, so no event can fall between them.

`end_streams()` (called when the service is told to stop) ends every `follow` of the running
event loop at once and makes new ones return after their history: open event streams must not
hold a stopping server up (uvicorn waits for open responses before its shutdown runs).
"""

from __future__ import annotations

import asyncio
import weakref
from collections.abc import AsyncIterator, Iterable
from typing import Any

__all__ = ["Broadcast", "Event", "end_streams", "streams_ended"]

#: (kind, data): kind "done" ends a stream.
Event = tuple[str, dict[str, Any]]

#: Per event loop (one service): set once its streams must end.
_ending: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, asyncio.Event] = (
    weakref.WeakKeyDictionary()
)


def _ending_event() -> asyncio.Event:
    loop = asyncio.get_running_loop()
    event = _ending.get(loop)
    if event is None:
        event = _ending[loop] = asyncio.Event()
    return event


def end_streams() -> None:
    """End every event stream of the running loop now, and any started later."""
    _ending_event().set()


def streams_ended() -> bool:
    """True once `end_streams` was called on the running loop."""
    return _ending_event().is_set()


class Broadcast:
    """Publish events to any number of `follow` iterators."""

    def __init__(self) -> None:
        self._queues: set[asyncio.Queue[Event]] = set()

    def publish(self, kind: str, data: dict[str, Any]) -> None:
        for queue in self._queues:
            queue.put_nowait((kind, data))

    async def follow(self, history: Iterable[Event], done: Event | None
                     ) -> AsyncIterator[Event]:
        """`history`, then `done` if the job already ended, else live events up to "done"
        (or until the service stops: `end_streams`).

        Call it in the same step as the history is taken (no await in between)."""
        queue: asyncio.Queue[Event] = asyncio.Queue()
        self._queues.add(queue)
        ending = _ending_event()
        try:
            for event in history:
                yield event
            if done is not None:
                yield done
                return
            while not ending.is_set():
                getter = asyncio.ensure_future(queue.get())
                stopper = asyncio.ensure_future(ending.wait())
                try:
                    await asyncio.wait({getter, stopper}, return_when=asyncio.FIRST_COMPLETED)
                finally:
                    stopper.cancel()
                    if not getter.done():
                        getter.cancel()
                if not getter.done() or getter.cancelled():
                    return
                event = getter.result()
                yield event
                if event[0] == "done":
                    return
        finally:
            self._queues.discard(queue)
