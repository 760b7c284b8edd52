"""A small host for `gcs.flight.host.vehicle_process` tests: it answers, raises, notifies, and
writes a file when it is closed (what the service's host does there is land a flight)."""

from __future__ import annotations

import asyncio
import os
from pathlib import Path

from gcs.errors import StateConflict
from gcs.flight.host.vehicle_process import HostContext


class EchoHost:
    """Answers in the child process; `closed_mark` is written by `close`."""

    def __init__(self, context: HostContext, closed_mark: str) -> None:
        self._context = context
        self._closed_mark = Path(closed_mark)

    def pid(self) -> int:
        """The child's process id."""
        return os.getpid()

    async def add(self, a: int, b: int, *, times: int = 1) -> int:
        """A coroutine answered by value."""
        await asyncio.sleep(0)
        return (a + b) * times

    def refuse(self) -> None:
        """A GcsError with attributes of its own."""
        raise StateConflict("fleet", "no")

    def announce(self, count: int) -> int:
        """`count` notices, in order."""
        for i in range(count):
            self._context.notify("tick", {"i": i})
        return count

    async def wait(self) -> None:
        """Never answers (until the process ends)."""
        await asyncio.sleep(3600)

    def close(self) -> None:
        """Mark that the host was closed."""
        self._closed_mark.write_text(str(os.getpid()))
