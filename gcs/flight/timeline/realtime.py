"""Real-time scheduling for the calling thread: SCHED_RR priority 1, asked for once, with
what to restore and how it went, so the streamer and the vehicle loop ask the same way.

Why: on a machine whose cores are busy (other processes, a simulator), the kernel leaves a
woken GCS thread waiting for a core for several ms, which is most of the send jitter; a
real-time thread runs as soon as it wakes. The flight's waits are bounded (a fraction of a
tick), so it cannot starve the machine, and Linux keeps 5% of each core for ordinary
processes anyway (sched_rt_runtime_us).
"""

from __future__ import annotations

import contextlib
import gc
import os
from dataclasses import dataclass

__all__ = ["REALTIME", "Scheduling", "enter_realtime", "leave_realtime", "settle_heap"]

#: How a thread that got real-time scheduling reports it.
REALTIME = "SCHED_RR 1"


@dataclass(frozen=True)
class Scheduling:
    """The outcome of `enter_realtime`: what the thread runs with, and what it ran with."""

    text: str
    """``SCHED_RR 1``, or ``ordinary (real-time refused: <reason>)``."""
    previous: tuple[int, os.sched_param] | None = None
    """The policy and parameters to restore; None when nothing changed."""

    @property
    def granted(self) -> bool:
        return self.previous is not None


def enter_realtime() -> Scheduling:
    """SCHED_RR 1 for the calling thread. Threads and processes it starts get ordinary
    scheduling (RESET_ON_FORK), not this priority. Refused without CAP_SYS_NICE or an
    `rtprio` limit, and off Linux; then nothing changes and the text says why."""
    try:
        previous = (os.sched_getscheduler(0), os.sched_getparam(0))
        os.sched_setscheduler(0, os.SCHED_RR | os.SCHED_RESET_ON_FORK, os.sched_param(1))
    except (AttributeError, OSError) as exc:
        return Scheduling(f"ordinary (real-time refused: {exc})")
    return Scheduling(REALTIME, previous)


def leave_realtime(scheduling: Scheduling) -> None:
    """Give back what the thread ran with before `enter_realtime` (nothing if refused)."""
    if scheduling.previous is not None:
        with contextlib.suppress(OSError):
            os.sched_setscheduler(0, *scheduling.previous)


def settle_heap() -> None:
    """Collect the whole heap once and freeze what is left: before a flight streams, and
    again once it ended.

    Python's oldest-generation collection walks every tracked object of the process: with the
    imported libraries (numpy, pymavlink, the planner) that is 100-160 ms, in which no tick is
    sent, once every few seconds of a 50 Hz flight (measured: 27-37 missed ticks in a 30 s
    8-vehicle flight, real-time priority or not). Frozen objects are never walked again (they
    are still freed by reference counting), so later collections see only what the flight
    itself allocates. A frozen reference cycle is never collected, so what was frozen is
    unfrozen first: a flight that ended in an error (its executor, traceback and record in one
    cycle) is freed by the next call."""
    gc.unfreeze()
    gc.collect()
    gc.freeze()
