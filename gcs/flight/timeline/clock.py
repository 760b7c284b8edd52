"""The flight clock: flight time on the streamer's ticks, stopped by pauses.

Flight time 0 is the streamer tick at which every vehicle's plan track starts
(`FlightClock.begin`); a pause stops the clock at a plan tick and a resume moves the flight's
start tick on by the ticks spent paused, so flight time = (tick - start tick) / rate outside
pauses. `pauses` keeps [start, end] of each pause on the GCS clock for the record.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

__all__ = ["FlightClock", "Pause"]


@dataclass
class Pause:
    """A pause under way."""

    tick: int
    """Streamer tick from which the fleet holds."""
    plan_tick: int
    """The plan's tick (flight time * rate) every vehicle holds."""
    shift: float = 0.0
    """Seconds of plan time from the tick reached to the one held (`stop`; negative: the
    fleet holds a little back along the plan)."""
    held: list[str] = field(default_factory=list)
    """The vehicles set to hold the plan's setpoint of `plan_tick`."""


class FlightClock:
    """Flight time and its pauses, for a streamer at `rate` Hz whose tick 0 is `epoch`."""

    def __init__(self, rate: float, epoch: float, t0: float) -> None:
        self.rate = float(rate)
        self.epoch = epoch
        """`time.monotonic` instant of streamer tick 0."""
        self.t0 = t0
        """`time.monotonic` instant of GCS-clock 0."""
        self.start: float | None = None
        """GCS-clock time (s) of flight time 0 (None before the plan started)."""
        self.start_tick = 0
        """Streamer tick of flight time 0, moved on by every pause."""
        self.pauses: list[list[float | None]] = []
        """[start, end] of every pause (GCS clock, s; end None while paused)."""
        self.paused_total = 0.0
        self.pause: Pause | None = None

    def tick_time(self, tick: int) -> float:
        """GCS-clock time (s) of streamer `tick`."""
        return self.epoch + tick / self.rate - self.t0

    def now(self) -> float:
        return time.monotonic() - self.t0

    def begin(self, tick: int) -> None:
        """Flight time 0 is streamer `tick`."""
        self.start = self.tick_time(tick)
        self.start_tick = tick

    def flight_time(self) -> float | None:
        """Seconds of flight time (None before it started); it stops while paused."""
        if self.start is None:
            return None
        if self.pause is not None:
            return self.pause.plan_tick / self.rate
        return self.now() - self.start - self.paused_total

    def stop(self, tick: int, plan_tick: int | None = None) -> Pause:
        """Pause from streamer `tick`: returns the pause (its plan tick is where to hold:
        `plan_tick`, or the plan tick reached by default)."""
        assert self.pause is None and self.start is not None
        reached = tick - self.start_tick
        at = reached if plan_tick is None else max(0, plan_tick)
        self.pause = Pause(tick, at, shift=(at - reached) / self.rate)
        self.pauses.append([self.tick_time(tick), None])
        return self.pause

    def restart(self, tick: int) -> tuple[Pause, float]:
        """Resume at streamer `tick`: returns the pause that ended and its length (s)."""
        pause = self.pause
        assert pause is not None
        paused = (tick - pause.tick) / self.rate
        self.paused_total += paused - pause.shift
        self.start_tick = tick - pause.plan_tick
        self.pauses[-1][1] = self.tick_time(tick)
        self.pause = None
        return pause, paused

    def end_pause(self) -> Pause | None:
        """Forget a pause (the flight is ending); its interval ends now. Returns it."""
        pause, self.pause = self.pause, None
        if pause is not None and self.pauses and self.pauses[-1][1] is None:
            self.pauses[-1][1] = self.now()
        return pause
