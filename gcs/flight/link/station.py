"""The ground station's own stalls: spans in which its event loop did not run.

A station whose computer is busy (other processes on its cores, a blocking callback) wakes up
late: meanwhile nothing was sent and no datagram was read, so a vehicle's messages look late
and its position looks stale although the vehicle did nothing wrong. `StationStalls` collects
those spans (the monitor's and the streamer's late wake-ups) so that the checks count a gap in
*station-running time* (the gap minus its overlap with the station's stalls), and deadlines of
the vehicle procedure run on `StationStalls.clock` (monotonic time minus every stall so far).

`StallReport` turns the stalls into `station_stall` events: only stalls of at least
`STALL_EVENT_S`, and at most one event per `STALL_EVENT_EVERY_S` (the ones in between are
summed into the next), so a busy machine does not flood the flight's log.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

__all__ = ["STALL_EVENT_EVERY_S", "STALL_EVENT_S", "STALL_NOTE_S", "Clock", "StallReport",
           "StationStalls"]

#: A wake-up this much later than planned is a stall of the station (discounted from gaps).
STALL_NOTE_S = 0.1
#: Stalls at least this long are reported as `station_stall` events.
STALL_EVENT_S = 0.25
#: At most one `station_stall` event per this many seconds.
STALL_EVENT_EVERY_S = 5.0
#: How far back stalls are kept (longer than any gap a check judges).
_KEEP_S = 120.0
_KEEP_SPANS = 4096

#: A clock in seconds (`time.monotonic` or `StationStalls.clock`).
Clock = Callable[[], float]


class StationStalls:
    """The spans (monotonic seconds) in which the station did not run, merged and bounded."""

    def __init__(self) -> None:
        self.spans: deque[tuple[float, float]] = deque(maxlen=_KEEP_SPANS)
        """Disjoint (start, end) spans, oldest first."""
        self.total = 0.0
        """Seconds of stall noted so far."""
        self.listeners: list[Callable[[float, float], None]] = []
        """Called with (start, end) of every stall noted."""

    def note(self, start: float, end: float) -> None:
        """The station did not run from `start` to `end` (overlaps are merged); listeners
        hear of it when it adds stall time."""
        if end <= start:
            return
        before = self.total
        # merge with every noted span it touches (the monitor and the streamer see the
        # same stall from different wake-ups)
        later = []
        while self.spans and start <= self.spans[-1][1]:
            s, e = self.spans.pop()
            if e < start or s > end:  # a later span it does not touch
                later.append((s, e))
                continue
            self.total -= e - s
            start, end = min(s, start), max(e, end)
        self.spans.append((start, end))
        self.spans.extend(reversed(later))
        self.total += end - start
        if self.total <= before:
            return
        while self.spans and self.spans[0][1] < end - _KEEP_S:
            self.spans.popleft()
        for listener in self.listeners:
            listener(start, end)

    def overlap(self, start: float, end: float) -> float:
        """Seconds of [start, end] in which the station stalled."""
        out = 0.0
        for s, e in reversed(self.spans):
            if e <= start:
                break
            out += max(0.0, min(e, end) - max(s, start))
        return out

    def running(self, start: float, end: float) -> float:
        """Station-running seconds from `start` to `end`."""
        return max(0.0, end - start - self.overlap(start, end))

    def age(self, since: float | None, now: float) -> float:
        """Station-running seconds since `since` (inf when None)."""
        return float("inf") if since is None else self.running(since, now)

    def ended_since(self, since: float) -> float:
        """Seconds of the stalls that ended after `since` (how far behind the plan a vehicle
        may be that got no setpoints meanwhile)."""
        return sum(e - s for s, e in self.spans if e > since)

    def clock(self) -> float:
        """Monotonic seconds minus every stall so far: deadlines on it do not expire while
        the station itself is stalled."""
        return time.monotonic() - self.total


class StallReport:
    """Rate-limited `station_stall` event texts (see the module)."""

    def __init__(self, threshold: float = STALL_EVENT_S,
                 every: float = STALL_EVENT_EVERY_S) -> None:
        self.threshold = threshold
        self.every = every
        self.count = 0
        """Stalls reported so far (in events or pending)."""
        self.longest = 0.0
        self._pending: list[float] = []
        self._last_event = -float("inf")
        self._last_start = -float("inf")

    def add(self, start: float, end: float) -> str | None:
        """Take one stall (a span merged from several wake-ups keeps its start, so it counts
        once); returns an event text when one is due, else None."""
        duration, now = end - start, end
        if duration < self.threshold:
            return None
        if start == self._last_start and self._pending:
            self._pending[-1] = duration
        elif start != self._last_start:
            self.count += 1
            self._pending.append(duration)
        self._last_start = start
        self.longest = max(self.longest, duration)
        if now - self._last_event < self.every:
            return None
        return self.flush(now)

    def flush(self, now: float) -> str | None:
        """The text for the stalls not reported yet (None when there are none)."""
        if not self._pending:
            return None
        pending, self._pending = self._pending, []
        self._last_event = now
        if len(pending) == 1:
            return f"station stalled {pending[0]:.2f} s (its own loop, not a vehicle)"
        return (f"station stalled {len(pending)} times, longest {max(pending):.2f} s, "
                f"{sum(pending):.2f} s in all (its own loop, not a vehicle)")
