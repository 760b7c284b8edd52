"""Waiting for something to become true, one definition for every test.

`until` is awaited inside an event loop; `wait_for` is its twin for synchronous tests (a
TestClient, a subprocess). Both return the first true value of `condition()` and fail naming
`what` (and `detail()`, the state that would explain it) once `timeout` seconds have passed:
a loose bound for a busy machine, never a measurement. `reached` awaits a flight's clock;
`line_with` is the condition of a child process's output holding a text. `every` is the one
periodic loop that is not a wait: a sampler or a feed, run as a task until cancelled.
"""

from __future__ import annotations

import asyncio
import inspect
import queue
import time
from collections.abc import Awaitable, Callable
from typing import NoReturn, Protocol, TypeVar

from gcs.phases import FlightPhase

__all__ = ["ENDED", "ClockedFlight", "every", "line_with", "reached", "until", "wait_for"]

T = TypeVar("T")


def _timed_out(what: str, timeout: float, detail: Callable[[], object] | None) -> str:
    """The failure message of a wait that ran out of time."""
    said = f"timed out after {timeout:g} s waiting for {what}"
    return said if detail is None else f"{said}: {detail()}"


async def until(condition: Callable[[], T | Awaitable[T]], what: str = "the condition",
                timeout: float = 60.0, poll: float = 0.05, *,
                detail: Callable[[], object] | None = None) -> T:
    """Await `condition()` becoming true (checked every `poll` s, the loop running between);
    `condition` may be a coroutine function (an HTTP client's request, say)."""
    deadline = time.monotonic() + timeout  # bound
    while True:
        value = condition()
        if inspect.isawaitable(value):
            value = await value
        if value:
            return value
        assert time.monotonic() < deadline, _timed_out(what, timeout, detail)
        await asyncio.sleep(poll)


def wait_for(condition: Callable[[], T], what: str = "the condition", timeout: float = 60.0,
             poll: float = 0.05, *, detail: Callable[[], object] | None = None) -> T:
    """Block until `condition()` is true (checked every `poll` s)."""
    deadline = time.monotonic() + timeout  # bound
    while not (value := condition()):
        assert time.monotonic() < deadline, _timed_out(what, timeout, detail)
        time.sleep(poll)
    return value


def line_with(lines: queue.Queue[str], text: str, seen: list[str]) -> Callable[[], str | None]:
    """A condition to wait for: the first line holding `text` among those read so far from
    `lines` (a process's output, read on a thread), each line read moved to `seen`."""
    def check() -> str | None:
        while not lines.empty():
            seen.append(lines.get())
            if text in seen[-1]:
                return seen[-1]
        return None

    return check


async def every(period: float, action: Callable[[], object]) -> NoReturn:
    """Call `action()` every `period` s until cancelled (run it as a task)."""
    while True:
        action()
        await asyncio.sleep(period)


class ClockedFlight(Protocol):
    """What `reached` reads of a flight (`gcs.flight.run.executor.FlightExecutor`)."""

    @property
    def phase(self) -> FlightPhase: ...

    def flight_time(self) -> float | None: ...


#: The phases a flight ends in.
ENDED = (FlightPhase.FINISHED, FlightPhase.ABORTED, FlightPhase.FAILED)


async def reached(flight: ClockedFlight, t: float) -> None:
    """Await flight time `t` on `flight`'s clock; fail if the flight ends first."""
    def there() -> bool:
        assert flight.phase not in ENDED, f"the flight ended ({flight.phase}) before t={t:g} s"
        return (flight.flight_time() or -1.0) >= t

    await until(there, f"flight time {t:g} s", timeout=t + 120.0, poll=0.02)
