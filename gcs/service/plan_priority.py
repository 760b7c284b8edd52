"""The embedded cluster's planning workers run at a lower CPU priority than the service.

A plan is CPU-bound for seconds to minutes; a flight needs a little CPU every 20 ms. On a
machine where both run (the embedded cluster shares the service's cores), the workers'
threads are set to niceness `PLAN_WORKER_NICENESS`, so the kernel gives a flight's ticks the
CPU first and the plans the rest. A Dask worker plugin does it, so a worker the service
restarts (to stop a task) is lowered too. Workers of an external cluster are left as their
operator started them.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

__all__ = ["PLAN_WORKER_NICENESS", "LowerPriority", "lower_priority"]

#: Niceness of the embedded cluster's worker processes (0 normal, 19 lowest): at 5 a busy
#: worker gets about a third of the CPU share of a busy service thread (Linux CFS weights).
PLAN_WORKER_NICENESS = 5


def lower_priority(niceness: int) -> int:
    """Raise the niceness of every thread of this process to at least `niceness` (Linux
    keeps it per thread; elsewhere the process's); returns the calling thread's niceness."""
    tasks = Path("/proc/self/task")
    ids = [int(t.name) for t in tasks.iterdir()] if tasks.is_dir() else [0]
    for tid in ids:
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            if os.getpriority(os.PRIO_PROCESS, tid) < niceness:
                os.setpriority(os.PRIO_PROCESS, tid, niceness)
    return os.getpriority(os.PRIO_PROCESS, 0)


class LowerPriority(WorkerPlugin):
    """Sets each worker's threads, and those it starts later, to `niceness`."""

    name = "fleetplan-lower-priority"

    def __init__(self, niceness: int = PLAN_WORKER_NICENESS) -> None:
        self.niceness = niceness

    def setup(self, worker: Any) -> None:
        lower_priority(self.niceness)
