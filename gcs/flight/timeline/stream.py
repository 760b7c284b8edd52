"""The shared clock and its setpoint streaming loop.

One `Streamer` ticks at the stream rate for the whole fleet: at tick k (scheduled instant
``epoch + k / rate`` on `time.monotonic`) it sends every assigned vehicle the setpoint of its
track for that tick, all within the same tick, so the shared flight clock is simply "tick k".
A vehicle's track is assigned with the tick at which its tick 0 falls; the plan's tracks of all
vehicles get the same start tick, which is what starts the flight clock.

If the loop wakes up more than a whole tick late it sends the current tick (never a burst of
old ones) and counts the ticks it skipped. Each send's lateness against its tick's scheduled
instant is recorded (`lateness`), which gives the send-instant jitter of the flight record and
of `bench/stream.py`.

Timing: asyncio's timers wake up to ~1 ms late (epoll counts in milliseconds) and encoding
a MAVLink message takes tens of microseconds, so the loop wakes early by the time the last
tick took to encode plus `WAKE_MARGIN`, encodes every vehicle's message for the tick, waits
out the remaining fraction of a millisecond on the clock itself, and then only sends the
ready datagrams. Measured with 50 vehicles at 50 Hz (bench/stream.py, README): p50/p99
lateness 1.5/4.2 ms when sleeping on the timer, 0.5/3.8 ms (medians of 3 runs) like this,
for about 2.5 ms of waiting on the clock per tick (12% of a core at 50 Hz, 5% at 20 Hz).

Stalls (`Streamer.stalls`): a wake-up more than `STALL_S` late is counted as *descheduled*
(the thread waited runnable for a core: another process ran) or *busy* (its own callbacks
ran). At 100 vehicles on a busy 2-core machine nearly all stalls are descheduled; garbage
collection and telemetry handling are not the cause (bench/stream.py, README). Hence
`realtime=True`: the loop's thread runs at SCHED_RR 1 while streaming, when the process may
(CAP_SYS_NICE or an rtprio limit, e.g. ``chrt -r 1`` or systemd's CPUSchedulingPolicy).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from gcs.flight.link.interface import Link
from gcs.flight.link.setpoints import Setpoint, SetpointTrack, hold_track
from gcs.flight.link.station import STALL_NOTE_S
from gcs.flight.timeline.realtime import enter_realtime, leave_realtime
from gcs.wire import time_boot_ms

__all__ = ["STALL_S", "Assignment", "SendCallback", "Streamer", "jitter_stats"]

#: Called after each send with (vehicle id, tick, setpoint, send instant).
SendCallback = Callable[[str, int, Setpoint, float], None]

#: How much earlier than (encoding time of the last tick) the loop wakes up before a tick:
#: covers asyncio's millisecond timer resolution and telemetry handled just before the tick;
#: the rest is a short wait on the clock (1.5 ms gave p99 4.3 ms, 3 ms 2.6 ms, 5 ms 1.6 ms).
WAKE_MARGIN = 0.003
#: A wake-up this much later than planned is a stall (`Streamer.stalls`).
STALL_S = 0.002


@dataclass
class Assignment:
    """What one vehicle is being streamed."""

    link: Link
    track: SetpointTrack
    start_tick: int
    """Streamer tick at which the track's tick 0 is sent."""
    last: Setpoint | None = None
    """The last setpoint sent."""


class Streamer:
    """The fleet's one setpoint loop at `rate` Hz (see the module docstring)."""

    def __init__(self, rate: float, boot_epoch: float | None = None, *,
                 realtime: bool = False) -> None:
        self.rate = float(rate)
        self.realtime = realtime
        """Ask for real-time scheduling (SCHED_RR 1) for the loop's thread while streaming,
        see `scheduling`; off by default (today's behaviour)."""
        self.scheduling = "ordinary"
        """What the loop's thread ran with: ``ordinary``, ``SCHED_RR 1``, or why real-time
        was refused (it needs CAP_SYS_NICE or an rtprio limit, e.g. `chrt`/systemd)."""
        self.period = 1.0 / self.rate
        self.epoch = time.monotonic()
        """Instant of tick 0."""
        self.boot_epoch = self.epoch if boot_epoch is None else boot_epoch
        """The GCS clock's zero, from which `time_boot_ms` counts."""
        self.assignments: dict[str, Assignment] = {}
        self.pending: dict[str, tuple[int, Assignment]] = {}
        """Tracks waiting for their switch tick (`switch`), as (switch tick, assignment): the
        current assignment streams until then."""
        self.listeners: list[SendCallback] = []
        self.tick = -1
        """The last tick sent."""
        self.missed_ticks = 0
        self.lateness: list[float] = []
        """Send instant minus scheduled tick instant (s), one per message, while
        `measuring` is true."""
        self.measuring = False
        self.stalls = {"busy": 0, "descheduled": 0}
        """Wake-ups more than `STALL_S` late while `measuring`, by cause: ``descheduled`` when
        the loop's thread waited at least half of the delay runnable but not running (the OS
        ran another process: Linux's /proc/thread-self/schedstat), else ``busy`` (this
        thread's own callbacks ran: telemetry, heartbeats, garbage collection)."""
        self.stall_listeners: list[Callable[[float, float], None]] = []
        """Called with (planned, actual) wake-up instant of every wake-up more than
        `gcs.flight.link.station.STALL_NOTE_S` late, measuring or not (the station's stalls)."""
        self._task: asyncio.Task[None] | None = None

    def tick_time(self, tick: int) -> float:
        """Scheduled instant (time.monotonic) of `tick`."""
        return self.epoch + tick * self.period

    def next_tick(self) -> int:
        """The first tick not yet sent."""
        return max(self.tick + 1, math.ceil((time.monotonic() - self.epoch) * self.rate))

    def assign(self, vehicle_id: str, link: Link, track: SetpointTrack,
               start_tick: int | None = None) -> int:
        """Stream `track` to `link` from `start_tick` (default: the next tick); returns it."""
        tick = self.next_tick() if start_tick is None else start_tick
        self.pending.pop(vehicle_id, None)  # an assignment now overrides a later switch
        self.assignments[vehicle_id] = Assignment(link, track, tick)
        return tick

    def switch(self, vehicle_id: str, link: Link, track: SetpointTrack,
               at_tick: int, origin: int | None = None) -> None:
        """Stream `track` to `link` from `at_tick` on, its tick 0 at `origin` (default
        `at_tick`: tick 0 then); until that tick the vehicle's current assignment goes on
        (unlike `assign`, which replaces it at once and sends the new track's first position
        at rest before its start tick)."""
        start = at_tick if origin is None else origin
        if vehicle_id not in self.assignments or at_tick <= self.next_tick():
            self.assign(vehicle_id, link, track, start)
            return
        self.pending[vehicle_id] = (at_tick, Assignment(link, track, start))

    def cancel_switch(self, vehicle_id: str) -> bool:
        """Drop the switch waiting for a vehicle (its current assignment goes on); False
        when none waited (it may have taken over already)."""
        return self.pending.pop(vehicle_id, None) is not None

    def freeze(self, vehicle_ids: Iterable[str] | None = None) -> None:
        """Every stream (or those of `vehicle_ids`) holds its last setpoint from now on, so
        nothing moves on along a plan; a stream that has sent nothing yet is left as it is."""
        for vid in list(self.assignments) if vehicle_ids is None else vehicle_ids:
            assignment = self.assignments.get(vid)
            if assignment is not None and assignment.last is not None:
                self.assign(vid, assignment.link, hold_track(
                    assignment.last.position, assignment.last.yaw, self.rate))

    def unassign(self, vehicle_id: str) -> None:
        """Stop streaming to a vehicle (and drop any switch waiting for it)."""
        self.assignments.pop(vehicle_id, None)
        self.pending.pop(vehicle_id, None)

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self._run(), name="setpoint-stream")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    def prepare_tick(self, tick: int) -> list[tuple[str, Assignment, Setpoint, bytes]]:
        """Every vehicle's setpoint for `tick`, encoded, ready to send."""
        boot_ms = time_boot_ms(self.tick_time(tick) - self.boot_epoch)
        if self.pending:  # almost always empty: no copy of it on every tick
            for vehicle_id, (switch_tick, waiting) in list(self.pending.items()):
                if switch_tick <= tick:  # its switch tick: it takes over
                    del self.pending[vehicle_id]
                    self.assignments[vehicle_id] = waiting
        ready = []
        for vehicle_id, assignment in list(self.assignments.items()):
            setpoint = assignment.track.at(tick - assignment.start_tick)
            ready.append((vehicle_id, assignment, setpoint,
                          assignment.link.pack_setpoint(setpoint, boot_ms)))
        return ready

    def _send_tick(self, tick: int, ready: list[tuple[str, Assignment, Setpoint, bytes]]
                   ) -> None:
        scheduled = self.tick_time(tick)
        measuring = self.measuring
        sent_at = []
        for _, assignment, _, buf in ready:
            assignment.link.send_packed(buf)
            sent_at.append(time.monotonic())
        # Bookkeeping and listeners only after every datagram of the tick has left.
        for (vehicle_id, assignment, setpoint, _), sent in zip(ready, sent_at, strict=True):
            assignment.last = setpoint
            if measuring:
                self.lateness.append(sent - scheduled)
            for listener in self.listeners:
                listener(vehicle_id, tick, setpoint, sent)
        self.tick = tick

    async def _run(self) -> None:
        try:
            schedstat: int | None = os.open("/proc/thread-self/schedstat", os.O_RDONLY)
        except OSError:  # not Linux: stalls are all counted as busy
            schedstat = None
        scheduling = enter_realtime() if self.realtime else None
        if scheduling is not None:
            self.scheduling = scheduling.text
        try:
            await self._loop(schedstat)
        finally:
            if schedstat is not None:
                os.close(schedstat)
            if scheduling is not None:
                leave_realtime(scheduling)

    async def _loop(self, schedstat: int | None) -> None:
        encode_time = 0.0
        while True:
            now = time.monotonic()
            due = math.floor((now - self.epoch) * self.rate + 1e-9)
            if due > self.tick:  # late: send the current tick now, never a burst
                if due > self.tick + 1 and self.tick >= 0:
                    self.missed_ticks += due - self.tick - 1
                self._send_tick(due, self.prepare_tick(due))
            else:
                tick = self.tick + 1
                began = time.monotonic()
                ready = self.prepare_tick(tick)
                encode_time = time.monotonic() - began
                while time.monotonic() < self.tick_time(tick):
                    pass  # a fraction of a millisecond: the clock, not the timer
                self._send_tick(tick, ready)
            wake = self.tick_time(self.tick + 1) - encode_time - WAKE_MARGIN
            measuring = self.measuring
            waited = _run_delay(schedstat) if measuring else 0.0
            await asyncio.sleep(max(0.0, wake - time.monotonic()))
            woke = time.monotonic()
            late = woke - wake
            if late > STALL_NOTE_S:
                for listener in self.stall_listeners:
                    listener(wake, woke)
            if late > STALL_S and measuring:
                descheduled = _run_delay(schedstat) - waited >= late / 2
                self.stalls["descheduled" if descheduled else "busy"] += 1


def _run_delay(schedstat: int | None) -> float:
    """Seconds this thread has waited runnable for a CPU (0 when unknown)."""
    if schedstat is None:
        return 0.0
    return int(os.pread(schedstat, 64, 0).split()[1]) * 1e-9


def jitter_stats(lateness: Sequence[float] | np.ndarray) -> dict[str, float]:
    """p50/p99/max of the send-instant lateness, in milliseconds."""
    values = np.asarray(lateness, dtype=float) * 1000.0
    if values.size == 0:
        return {"jitter_p50_ms": math.nan, "jitter_p99_ms": math.nan, "jitter_max_ms": math.nan}
    return {
        "jitter_p50_ms": float(np.percentile(values, 50)),
        "jitter_p99_ms": float(np.percentile(values, 99)),
        "jitter_max_ms": float(values.max()),
    }
