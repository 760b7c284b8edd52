"""`fleetplan fly --record FILE`: the flight record written as the flight goes.

So that a station that dies (kill -9, a crash, power loss) leaves what the flight did, the
record so far (``"partial": true``, the shape of the final record: `gcs.service.record_mirror`)
replaces FILE about once a second while anything new happened (events, telemetry), like the
service's journal; the final record replaces it at the end. Each write goes to FILE.tmp and
is renamed over FILE, so FILE always holds one whole JSON document. Only what is new since
the last write crosses from the vehicle loop (`record_delta`); the JSON is made and written
in a thread, and a failing write is said once and retried on the next beat: the flight never
waits for the disk.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from pathlib import Path
from typing import Any

import orjson

from gcs.flight.host.flight_handle import FlightHandle
from gcs.service.record_mirror import RecordMirror, record_delta

__all__ = ["PERIOD_S", "RecordFile", "write_json"]

#: Seconds between two writes of the record so far.
PERIOD_S = 1.0


def write_json(path: Path, doc: dict[str, Any]) -> None:
    """`doc` as JSON at `path`, whole or not at all (written beside it, then renamed)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY))
    os.replace(tmp, path)


class RecordFile:
    """Writes one flight's record so far to `path` every `PERIOD_S` until `close`."""

    def __init__(self, path: Path, handle: FlightHandle, period_s: float = PERIOD_S) -> None:
        self.path = path
        self._handle = handle
        self._period = period_s
        self._mirror = RecordMirror()
        self._task: asyncio.Task[None] | None = None
        self._failed = False

    def start(self) -> None:
        self._task = asyncio.ensure_future(self._loop())

    async def close(self) -> None:
        """Stop writing (the caller writes the final record)."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    async def _loop(self) -> None:
        while True:
            await asyncio.sleep(self._period)
            await self.write_so_far()

    async def write_so_far(self) -> bool:
        """Bring the copy up to date and write it when something was added; True when
        written."""
        mirror = self._mirror
        cursor = mirror.cursor()
        delta = await self._handle.with_recorder(lambda r: record_delta(r, cursor))
        if not delta["events"] and delta["meta"] is None and not any(
                any(column for column in v["columns"].values()) or v["modes"]
                for v in delta["vehicles"]):
            return False
        mirror.apply(delta)
        try:
            await asyncio.to_thread(write_json, self.path, mirror.snapshot())
        except (OSError, TypeError) as exc:
            if not self._failed:
                print(f"warning: cannot write the flight record so far to {self.path}: {exc}",
                      file=sys.stderr, flush=True)
            self._failed = True
            return False
        return True
