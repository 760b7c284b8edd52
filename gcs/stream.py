"""The shared clock and its setpoint streaming loop.

One `Streamer` ticks at the stream rate for the whole fleet: at tick k (scheduled instant
``epoch + k / rate`` on `time.monotonic`) it sends every assigned vehicle the setpoint of its
track for that tick, all within the same tick, so the shared mission clock is simply "tick k".
A vehicle's track is assigned with the tick at which its tick 0 falls; the plan's tracks of all
vehicles get the same start tick, which is what starts the mission clock.

If the loop wakes up more than a whole tick late it sends the current tick (never a burst of
old ones) and counts the ticks it skipped. Each send's lateness against its tick's scheduled
instant is recorded (`lateness`), which gives the send-instant jitter of the flight record and
of `bench/stream.py`.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gcs.link import VehicleLink
from gcs.setpoints import Setpoint, SetpointTrack, time_boot_ms

__all__ = ["Assignment", "SendCallback", "Streamer", "jitter_stats"]

#: Called after each send with (vehicle id, tick, setpoint, send instant).
SendCallback = Callable[[str, int, Setpoint, float], None]


@dataclass
class Assignment:
    """What one vehicle is being streamed."""

    link: VehicleLink
    track: SetpointTrack
    start_tick: int
    """Streamer tick at which the track's tick 0 is sent."""
    last: Setpoint | None = None
    """The last setpoint sent."""


class Streamer:
    """The fleet's one setpoint loop at `rate` Hz (see the module docstring)."""

    def __init__(self, rate: float, boot_epoch: float | None = None) -> None:
        self.rate = float(rate)
        self.period = 1.0 / self.rate
        self.epoch = time.monotonic()
        """Instant of tick 0."""
        self.boot_epoch = self.epoch if boot_epoch is None else boot_epoch
        """The GCS clock's zero, from which `time_boot_ms` counts."""
        self.assignments: dict[str, Assignment] = {}
        self.listeners: list[SendCallback] = []
        self.tick = -1
        """The last tick sent."""
        self.missed_ticks = 0
        self.lateness: list[float] = []
        """Send instant minus scheduled tick instant (s), one per message, while
        `measuring` is true."""
        self.measuring = False
        self._task: asyncio.Task[None] | None = None

    def tick_time(self, tick: int) -> float:
        """Scheduled instant (time.monotonic) of `tick`."""
        return self.epoch + tick * self.period

    def next_tick(self) -> int:
        """The first tick not yet sent."""
        return max(self.tick + 1, math.ceil((time.monotonic() - self.epoch) * self.rate))

    def assign(self, vehicle_id: str, link: VehicleLink, track: SetpointTrack,
               start_tick: int | None = None) -> int:
        """Stream `track` to `link` from `start_tick` (default: the next tick); returns it."""
        tick = self.next_tick() if start_tick is None else start_tick
        self.assignments[vehicle_id] = Assignment(link, track, tick)
        return tick

    def unassign(self, vehicle_id: str) -> None:
        """Stop streaming to a vehicle."""
        self.assignments.pop(vehicle_id, None)

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self._run(), name="setpoint-stream")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    def _send_tick(self, tick: int) -> None:
        scheduled = self.tick_time(tick)
        boot_ms = time_boot_ms(scheduled - self.boot_epoch)
        measuring = self.measuring
        for vehicle_id, assignment in list(self.assignments.items()):
            setpoint = assignment.track.at(tick - assignment.start_tick)
            assignment.link.send_setpoint(setpoint, boot_ms)
            sent = time.monotonic()
            assignment.last = setpoint
            if measuring:
                self.lateness.append(sent - scheduled)
            for listener in self.listeners:
                listener(vehicle_id, tick, setpoint, sent)
        self.tick = tick

    async def _run(self) -> None:
        while True:
            now = time.monotonic()
            due = math.floor((now - self.epoch) * self.rate + 1e-9)
            if due > self.tick:
                if due > self.tick + 1 and self.tick >= 0:
                    self.missed_ticks += due - self.tick - 1
                self._send_tick(due)
            await asyncio.sleep(max(0.0, self.tick_time(self.tick + 1) - time.monotonic()))


def jitter_stats(lateness: list[float] | np.ndarray) -> dict[str, float]:
    """p50/p99/max of the send-instant lateness, in milliseconds."""
    values = np.asarray(lateness, dtype=float) * 1000.0
    if values.size == 0:
        return {"jitter_p50_ms": math.nan, "jitter_p99_ms": math.nan, "jitter_max_ms": math.nan}
    return {
        "jitter_p50_ms": float(np.percentile(values, 50)),
        "jitter_p99_ms": float(np.percentile(values, 99)),
        "jitter_max_ms": float(values.max()),
    }
