"""Fan-out of a job's events (a plan's iterations, a flight's events) to every listener.

Each listener gets its own queue, bounded: a listener that falls `MAX_BACKLOG` events
behind (a client that stopped reading) is ended, so a stalled client never holds a growing
backlog; a client that reconnects gets the history again. `follow` yields what happened so
far first, then live events until a "done" one; taking the history and subscribing happen in
the same event-loop step, so no event can fall between them.

`end_streams()` (called when the service is told to stop) ends every `follow` of the running
event loop at once and makes new ones return after their history: open event streams must not
hold a stopping server up (uvicorn waits for open responses before its shutdown runs).
"""

from __future__ import annotations

import asyncio
import weakref
from collections import deque
from collections.abc import AsyncIterator, Iterable, Mapping
from typing import Any

__all__ = ["MAX_BACKLOG", "Broadcast", "Event", "end_streams", "streams_ended"]

#: Events a listener may fall behind before its stream is ended.
MAX_BACKLOG = 4096

#: (kind, data): kind "done" ends a stream.
Event = tuple[str, Mapping[str, Any]]

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


class _Listener:
    """One follower's backlog: events not yet taken, and whether it fell too far behind."""

    def __init__(self) -> None:
        self.events: deque[Event] = deque()
        self.ready = asyncio.Event()
        self.overrun = False

    def put(self, event: Event) -> None:
        if self.overrun:
            return
        if len(self.events) >= MAX_BACKLOG:
            self.overrun = True  # ended at its next wake-up; nothing more is kept for it
            self.events.clear()
        else:
            self.events.append(event)
        self.ready.set()


class Broadcast:
    """Publish events to any number of `follow` iterators."""

    def __init__(self) -> None:
        self._listeners: set[_Listener] = set()

    @property
    def listening(self) -> int:
        """Followers subscribed now."""
        return len(self._listeners)

    def publish(self, kind: str, data: Mapping[str, Any]) -> None:
        for listener in self._listeners:
            listener.put((kind, data))

    async def follow(self, history: Iterable[Event], done: Event | None
                     ) -> AsyncIterator[Event]:
        """`history`, then `done` if the job already ended, else live events up to "done"
        (or until the service stops: `end_streams`, or the follower falls `MAX_BACKLOG`
        events behind).

        Call it in the same step as the history is taken (no await in between)."""
        listener = _Listener()
        self._listeners.add(listener)
        ending = _ending_event()
        try:
            for event in history:
                yield event
            if done is not None:
                yield done
                return
            while not ending.is_set():
                if not listener.events and not listener.overrun:
                    listener.ready.clear()
                    waiter = asyncio.ensure_future(listener.ready.wait())
                    stopper = asyncio.ensure_future(ending.wait())
                    try:
                        await asyncio.wait({waiter, stopper},
                                           return_when=asyncio.FIRST_COMPLETED)
                    finally:
                        stopper.cancel()
                        waiter.cancel()
                    continue
                if listener.overrun:
                    return
                event = listener.events.popleft()
                yield event
                if event[0] == "done":
                    return
        finally:
            self._listeners.discard(listener)
