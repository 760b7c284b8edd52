"""Waiting for something to become true, one definition for every test.

`until` is awaited inside an event loop; `wait_for` is its twin for synchronous tests (a
TestClient, a subprocess). Both return the first true value of `condition()` and fail naming
`what` once `timeout` seconds have passed: a loose bound for a busy machine, never a
measurement. `reached` awaits a flight's clock.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Protocol, TypeVar

from gcs.phases import FlightPhase

__all__ = ["ENDED", "Flight", "reached", "until", "wait_for"]

T = TypeVar("T")


async def until(condition: Callable[[], T], what: str = "the condition", timeout: float = 60.0,
                poll: float = 0.05) -> T:
    """Await `condition()` becoming true (checked every `poll` s, the loop running between)."""
    deadline = time.monotonic() + timeout  # bound
    while not (value := condition()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(poll)
    return value


def wait_for(condition: Callable[[], T], what: str = "the condition", timeout: float = 60.0,
             poll: float = 0.05) -> T:
    """Block until `condition()` is true (checked every `poll` s)."""
    deadline = time.monotonic() + timeout  # bound
    while not (value := condition()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(poll)
    return value


class Flight(Protocol):
    """What `reached` reads of a flight (`gcs.flight.run.executor.FlightExecutor`)."""

    @property
    def phase(self) -> FlightPhase: ...

    def flight_time(self) -> float | None: ...


#: The phases a flight ends in.
ENDED = (FlightPhase.FINISHED, FlightPhase.ABORTED, FlightPhase.FAILED)


async def reached(flight: Flight, t: float) -> None:
    """Await flight time `t` on `flight`'s clock; fail if the flight ends first."""
    def there() -> bool:
        assert flight.phase not in ENDED, f"the flight ended ({flight.phase}) before t={t:g} s"
        return (flight.flight_time() or -1.0) >= t

    await until(there, f"flight time {t:g} s", timeout=t + 120.0, poll=0.02)
