"""A flight's state, events and flight record written to the store while it flies, and
its final write when it ends.

So that a crash (kill -9, power loss) keeps what a flight did, `FlightJournal` writes the
status and the events so far about once a second (batched: nothing is written when nothing
changed), and a snapshot of the flight record so far every few seconds (it grows with the
flight, so less often). The final write at the end of the flight (`write_final`) replaces all
of it; while the store refuses that (a full disk), the flight service keeps the final state
in memory and retries, and only a service that stops meanwhile leaves the flight `failed`
with the reason (`store_failure`), never stored as flying.

The record so far is the service's mirror of it (`gcs.service.record_mirror`: only what is
new since the last beat crosses from the vehicle process); the JSON is made and written in a
thread. A failing write is
logged and retried on the next beat: the flight itself never waits for the store.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable
from typing import Any

import orjson

from gcs.documents import FlightEvent
from gcs.service.store import Store

__all__ = ["FlightJournal", "RecordCopy", "Source", "store_failure", "write_final"]

log = logging.getLogger(__name__)

#: Seconds between writes of the status and events.
STATE_PERIOD_S = 1.0
#: Seconds between writes of the flight record so far.
RECORD_PERIOD_S = 5.0


#: How the journal takes the record so far (`RemoteFlight.record_so_far`).
RecordCopy = Callable[[], Awaitable[dict[str, Any]]]
#: What the journal reads each beat: (status, events so far, how to take the record so far,
#: or None while there is none).
Source = Callable[[], tuple[str, list[FlightEvent], RecordCopy | None]]


class FlightJournal:
    """Writes one live flight to the store periodically until `close`."""

    def __init__(self, store: Store, flight_id: str, source: Source, *,
                 state_period_s: float = STATE_PERIOD_S,
                 record_period_s: float = RECORD_PERIOD_S) -> None:
        self._store = store
        self._id = flight_id
        self._source = source
        self._state_period = state_period_s
        self._record_every = max(1, round(record_period_s / state_period_s))
        self._written: tuple[str | None, int] = (None, 0)
        self._stop = asyncio.Event()
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        """Start writing in the background."""
        self._task = asyncio.ensure_future(self._loop())

    async def close(self) -> None:
        """Stop writing, after a write under way has finished (the caller then writes the
        final state itself, which no late journal write may overwrite)."""
        self._stop.set()
        if self._task is not None:
            with contextlib.suppress(Exception):
                await self._task
            self._task = None

    async def _loop(self) -> None:
        beat = 0
        while not self._stop.is_set():
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._stop.wait(), self._state_period)
            if self._stop.is_set():
                return
            beat += 1
            await self.flush(with_record=beat % self._record_every == 0)

    async def flush(self, *, with_record: bool = False) -> bool:
        """Write the state now if it changed (and the record so far if asked); False if the
        store refused it."""
        status, live_events, take_record = self._source()
        state = (status, len(live_events))
        with_record = with_record and take_record is not None
        if state == self._written and not with_record:
            return True
        events = list(live_events)
        record = None
        if with_record and take_record is not None:
            try:
                record = await take_record()
            except Exception as exc:  # the flight ended meanwhile: the final write has it
                log.debug("no record so far of %s: %s", self._id, exc)

        def write() -> None:
            text = None
            if record is not None:
                try:
                    text = orjson.dumps(record, option=orjson.OPT_SERIALIZE_NUMPY).decode()
                except TypeError as exc:  # never let the record keep the events unstored
                    log.warning("flight record of %s not serialisable: %s", self._id, exc)
            self._store.update_flight(self._id, status=status, events=events,
                                         record_json=text)

        try:
            await asyncio.to_thread(write)
        except Exception as exc:
            log.warning("could not store flight %s so far (will retry): %s", self._id, exc)
            return False
        self._written = state
        return True


#: Background retries of failure writes (kept referenced until they end).
_retries: set[asyncio.Task[bool]] = set()


async def store_failure(store: Store, flight_id: str, reason: str,
                        events: list[FlightEvent], *, retry_s: float = 2.0,
                        attempts: int = 60) -> bool:
    """After the final write of a flight failed: mark it `failed` with `reason` (a small
    write, likelier to pass on a full disk). Tried once now; if that fails too, retried in the
    background (`attempts` times, every `retry_s`). True if stored now."""

    def write() -> None:
        store.update_flight(flight_id, status="failed", events=events, error=reason,
                               finished=True)

    async def retry() -> bool:
        for _ in range(attempts):
            await asyncio.sleep(retry_s)
            with contextlib.suppress(Exception):
                await asyncio.to_thread(write)
                return True
        return False

    try:
        await asyncio.to_thread(write)
        return True
    except Exception as exc:
        log.error("could not mark flight %s failed (retrying): %s", flight_id, exc)
    task = asyncio.ensure_future(retry())
    _retries.add(task)
    task.add_done_callback(_retries.discard)
    return False


async def write_final(store: Store, flight_id: str, *, status: str,
                      events: list[FlightEvent], summary: dict[str, Any] | None,
                      record: dict[str, Any] | None, error: str | None) -> None:
    """The final write of a flight: status, events, summary, record and error, in one
    update. Raises what the store raised: the caller keeps the flight in memory and retries
    (`gcs.service.flights`)."""

    def write() -> None:
        text = None
        if record is not None:
            # orjson: a flight record is megabytes; json.dumps would hold the GIL longer.
            text = orjson.dumps(record, option=orjson.OPT_SERIALIZE_NUMPY).decode()
        store.update_flight(flight_id, status=status, events=events, summary=summary,
                               record_json=text, error=error, finished=True)

    await asyncio.to_thread(write)
