"""Background asyncio tasks that their owner keeps until they end, and can cancel together.

asyncio keeps only a weak reference to a task: one nobody holds can be collected mid-run. The
executor, the flight service and the planning service each start such tasks (a fault's abort,
a flight, a plan job's watcher); `TaskSet` holds them until they are done.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Iterable, Iterator
from typing import Any, TypeVar

__all__ = ["TaskSet", "all_or_first_error"]

T = TypeVar("T")


class TaskSet:
    """The running background tasks of one owner."""

    def __init__(self) -> None:
        self._tasks: set[asyncio.Future[Any]] = set()

    def spawn(self, coro: Awaitable[T]) -> asyncio.Future[T]:
        """Run `coro` in the background on the running loop; held until it ends."""
        task = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    def __len__(self) -> int:
        return len(self._tasks)

    def __iter__(self) -> Iterator[asyncio.Future[Any]]:
        return iter(list(self._tasks))

    def cancel_all(self) -> None:
        """Ask every running task to stop."""
        for task in list(self._tasks):
            task.cancel()

    async def wait(self, timeout: float | None = None) -> None:
        """Wait up to `timeout` s for every running task to end (no error if some do not)."""
        if self._tasks:
            await asyncio.wait(list(self._tasks), timeout=timeout)


async def all_or_first_error(coros: Iterable[Awaitable[Any]]) -> None:
    """Run concurrently; on the first error cancel the rest and raise that error."""
    tasks = [asyncio.ensure_future(c) for c in coros]
    if not tasks:  # nothing to run (no vehicle left): asyncio.wait refuses an empty set
        return
    try:
        done, _pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
        for task in done:
            if task.exception() is not None:
                raise task.exception()  # type: ignore[misc]
    finally:
        for task in tasks:
            if not task.done():
                task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
