"""A vehicle link's quality as it is: loss, reordering, duplicates, latency and jitter.

Loss is counted from the MAVLink sequence numbers of one source (the pinned system and
autopilot component: a link admits no other, `gcs.flight.link`). A sequence number ahead of
the next one expected marks the skipped ones missing; one that arrives later fills its gap
and counts as reordered, not lost; one seen already counts as a duplicate. Numbers wrap at
255; within `WINDOW` behind the newest a late packet is told apart from a duplicate; after
`RESYNC_S` of silence, or a reboot (`restart`), the count starts again from the next packet.

Latency is half the round trip of TIMESYNC (the station sends one a second with its clock in
`ts1`; PX4, ArduPilot and the mock echo it back with their own `tc1`): a real round trip,
needing no common clock. Jitter is RFC 3550's interarrival jitter over LOCAL_POSITION_NED:
the change of (arrival time - the vehicle's `time_boot_ms`) from one message to the next,
smoothed by 1/16. It uses the sender's own timestamps, so it does not depend on the message's
rate (which PX4 varies) and measures only what the link adds.

`LinkWatch` judges each vehicle once a second over the last `WINDOW_S` seconds: degraded when
the recent loss reaches `DEGRADED_LOSS` (or jitter `DEGRADED_JITTER_S`, latency
`DEGRADED_LATENCY_S`) for two judgements in a row, recovered only when every figure is under
half its threshold for `RECOVER_S`: hysteresis, so a link on the edge does not flap. While
the station itself has stalled within the window (`gcs.flight.link.station`), late arrivals
are its own: only the loss is judged then.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from gcs.documents import LinkQualityReport

__all__ = ["DEGRADED_LOSS", "LinkQuality", "LinkWatch", "SequenceCounter", "Timing"]

#: How far behind the newest sequence number a packet is still judged late or repeated: half
#: the 8-bit space, the most that keeps "ahead" and "behind" apart (PX4's offboard link sends
#: about 410 messages/s, so 128 numbers are 0.3 s of reordering; further back a packet reads
#: as a jump ahead, so a burst of more than 127 lost in under `RESYNC_S` is undercounted).
WINDOW = 128
#: Silence after which the next packet starts the count again (s): across an outage the
#: numbers may have wrapped any number of times (the loss meanwhile is a lower bound).
RESYNC_S = 1.0
#: The window the degradation is judged over (s), and the least messages it needs.
WINDOW_S = 5.0
WINDOW_MIN = 20
#: A link is degraded at this recent loss (fraction), jitter (s) or latency (s) ...
DEGRADED_LOSS = 0.10
DEGRADED_JITTER_S = 0.05
DEGRADED_LATENCY_S = 0.25
#: ... and recovered once under half of each for this long (s).
RECOVER_S = 5.0

_NEW, _MISSING, _RECEIVED = 0, 1, 2


@dataclass
class SequenceCounter:
    """Messages of one source counted from their sequence numbers (see the module)."""

    received: int = 0
    """Distinct messages received."""
    lost: int = 0
    """Messages missing from the numbers and not (yet) arrived late."""
    reordered: int = 0
    """Messages that arrived after a later one (they filled their gap: not lost)."""
    duplicates: int = 0
    """Messages received again."""
    restarts: int = 0
    """Times the count started again (after a silence, or a reboot)."""
    last: int | None = None
    """The newest sequence number."""
    last_time: float | None = None
    settled_received: int = 0
    settled_lost: int = 0
    """Of the numbers that have left the window behind the newest (none of them can arrive
    late any more): those received and those lost. The window's delay, not the link's, is
    all that is behind; the figures of the last seconds are judged on these."""
    _state: bytearray = field(default_factory=lambda: bytearray(256), repr=False)

    def count(self, seq: int, now: float | None = None) -> None:
        """One message with sequence number `seq` (0..255) arrived at `now`."""
        now = time.monotonic() if now is None else now
        silent = self.last_time is not None and now - self.last_time > RESYNC_S
        self.last_time = now
        if self.last is None or silent:
            if self.last is not None:
                self.lost += (seq - self.last - 1) & 0xFF  # a lower bound across the silence
                self.restarts += 1
            self._restart(seq)
            return
        ahead = (seq - self.last - 1) & 0xFF
        if ahead < 256 - WINDOW:
            for k in range(1, ahead + 2):
                self._settle((self.last + k - WINDOW) & 0xFF)
            for k in range(ahead):
                self._state[(self.last + 1 + k) & 0xFF] = _MISSING
            self.lost += ahead
            self._state[seq] = _RECEIVED
            self.last = seq
            self.received += 1
            return
        state = self._state[seq]  # within WINDOW behind the newest (or the newest again)
        if state == _RECEIVED:
            self.duplicates += 1
            return
        if state == _MISSING:  # (else from before the count started: not counted lost)
            self.lost -= 1
        self._state[seq] = _RECEIVED
        self.reordered += 1
        self.received += 1

    def restart(self) -> None:
        """The sender rebooted: its numbers start anew (the next packet starts the count)."""
        self.restarts += 1
        self.last = None

    def _settle(self, number: int) -> None:
        """`number` leaves the window: received or lost for good."""
        state = self._state[number]
        if state == _RECEIVED:
            self.settled_received += 1
        elif state == _MISSING:
            self.settled_lost += 1
        self._state[number] = _NEW

    def _restart(self, seq: int) -> None:
        self._state[:] = bytes(256)  # nothing known behind the new start
        self._state[seq] = _RECEIVED
        self.last = seq
        self.received += 1

    @property
    def loss(self) -> float | None:
        """Lost over expected (received + lost), or None before any message."""
        total = self.received + self.lost
        return None if total == 0 else self.lost / total


@dataclass
class Timing:
    """Latency from TIMESYNC round trips, jitter from LOCAL_POSITION_NED (see the module)."""

    latency: float | None = None
    """Half the latest TIMESYNC round trip (s), smoothed by 1/4."""
    jitter: float = 0.0
    """RFC 3550 interarrival jitter (s)."""
    samples: int = 0
    _transit: float | None = None
    _sent: deque[int] = field(default_factory=lambda: deque(maxlen=8), repr=False)

    def request(self, now_ns: int) -> int:
        """The `ts1` of the TIMESYNC request sent now (the station's clock, ns)."""
        self._sent.append(now_ns)
        return now_ns

    def reply(self, ts1: int, now: float) -> None:
        """A TIMESYNC answer (tc1 != 0) echoing our `ts1`, received at `now` (monotonic s)."""
        if ts1 not in self._sent:
            return  # not ours (or answered twice): no round trip to measure
        self._sent.remove(ts1)
        half = (now - ts1 * 1e-9) / 2.0
        if 0.0 <= half < 30.0:
            previous = half if self.latency is None else self.latency
            self.latency = previous + (half - previous) / 4

    def stamped(self, arrival: float, sent: float) -> None:
        """A message the vehicle stamped `sent` (its clock, s) arrived at `arrival`."""
        transit = arrival - sent
        if self._transit is not None:
            self.jitter += (abs(transit - self._transit) - self.jitter) / 16.0
        self._transit = transit
        self.samples += 1

    def restart(self) -> None:
        """The vehicle's clock started again (a reboot): transit is measured anew."""
        self._transit = None


@dataclass
class LinkQuality:
    """One link's counter and timing, and the figures of the last few seconds."""

    counter: SequenceCounter = field(default_factory=SequenceCounter)
    timing: Timing = field(default_factory=Timing)
    _history: deque[tuple[float, int, int]] = field(
        default_factory=lambda: deque(maxlen=int(WINDOW_S) + 2), repr=False)

    def sample(self, now: float) -> None:
        """Note the counts now (about once a second) for `recent`: the lost ones only once
        they can no longer arrive late, so that packets merely delayed never count."""
        c = self.counter
        self._history.append((now, c.settled_received, c.settled_lost))

    def recent(self) -> tuple[int, int] | None:
        """(received, lost) over the last `WINDOW_S` of samples, or None before two."""
        if len(self._history) < 2:
            return None
        t1, received1, lost1 = self._history[-1]
        start = self._history[0]
        for entry in self._history:
            if t1 - entry[0] <= WINDOW_S + 0.5:
                start = entry
                break
        return received1 - start[1], lost1 - start[2]

    def report(self) -> LinkQualityReport:
        """JSON-ready figures (None: unknown): the `link_quality` of health and the record."""
        c, t = self.counter, self.timing
        recent = self.recent()
        recent_loss = (None if recent is None or sum(recent) == 0
                       else 100.0 * recent[1] / sum(recent))
        return {
            "received": c.received, "lost": c.lost, "reordered": c.reordered,
            "duplicates": c.duplicates, "restarts": c.restarts,
            "loss_pct": None if c.loss is None else round(100.0 * c.loss, 2),
            "recent_loss_pct": None if recent_loss is None else round(recent_loss, 2),
            "latency_ms": None if t.latency is None else round(1e3 * t.latency, 1),
            "jitter_ms": None if t.samples < 2 else round(1e3 * t.jitter, 1),
        }


def describe(q: LinkQuality) -> str:
    """The figures in one line, for events."""
    r = q.report()
    recent = q.recent()
    parts = [f"loss {_pct(r['recent_loss_pct'])} over the last {WINDOW_S:g} s"
             + ("" if recent is None else f" ({recent[1]} of {sum(recent)})"),
             f"latency {_ms(r['latency_ms'])}", f"jitter {_ms(r['jitter_ms'])}",
             f"reordered {r['reordered']}, duplicates {r['duplicates']} in all"]
    return ", ".join(parts)


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f}%"


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f} ms"


@dataclass
class _Judged:
    degraded: bool = False
    bad_in_row: int = 0
    good_since: float | None = None


class LinkWatch:
    """Once a second per link: `on_degraded(vehicle, text)` when it degrades and
    `on_recovered(vehicle, text)` when it is good again, with hysteresis (see the module)."""

    def __init__(self, on_degraded: Callable[[str, str], None],
                 on_recovered: Callable[[str, str], None]) -> None:
        self.on_degraded = on_degraded
        self.on_recovered = on_recovered
        self._judged: dict[str, _Judged] = {}
        self._next = -math.inf

    def check(self, links: dict[str, LinkQuality], now: float,
              station_stalled: bool = False) -> None:
        """Sample and judge every link when a second has passed since the last time;
        `station_stalled`: the station itself stalled within the window, so late arrivals
        are its own, and only the loss is judged."""
        if now < self._next:
            return
        self._next = now + 1.0
        for vid, quality in links.items():
            quality.sample(now)
            self._judge(vid, quality, now, station_stalled)

    def _judge(self, vid: str, q: LinkQuality, now: float, station_stalled: bool) -> None:
        judged = self._judged.setdefault(vid, _Judged())
        recent = q.recent()
        loss = (None if recent is None or sum(recent) < WINDOW_MIN
                else recent[1] / sum(recent))
        timed = q.timing.samples >= WINDOW_MIN and not station_stalled
        jitter = q.timing.jitter if timed else None
        latency = q.timing.latency if not station_stalled else None
        figures = ((loss, DEGRADED_LOSS), (jitter, DEGRADED_JITTER_S),
                   (latency, DEGRADED_LATENCY_S))
        bad = any(v is not None and v >= limit for v, limit in figures)
        good = all(v is None or v < limit / 2 for v, limit in figures)
        if not judged.degraded:
            judged.bad_in_row = judged.bad_in_row + 1 if bad else 0
            if judged.bad_in_row >= 2:
                judged.degraded, judged.good_since = True, None
                self.on_degraded(vid, describe(q))
            return
        if not good:
            judged.good_since = None
        elif judged.good_since is None:
            judged.good_since = now
        elif now - judged.good_since >= RECOVER_S:
            judged.degraded, judged.bad_in_row = False, 0
            self.on_recovered(vid, describe(q))
