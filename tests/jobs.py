"""How many test processes `make test` runs: one per core, plus one when the machine is idle.

Much of the suite waits on real-time mock flights, so on an idle machine a process more than
the cores keeps them busy (a 2-core machine: 584 s with 2, 464-493 s with 3). On a machine
that is already busy the extra process only adds contention, and the suite's flights run with
less slack. Idle means more than half of the CPU time idle over `SAMPLE_S` (from /proc/stat;
where that cannot be read, one per core). At most `MAX_JOBS`."""

from __future__ import annotations

import os
import time

#: How long the machine's load is sampled (s).
SAMPLE_S = 1.0
MAX_JOBS = 3


def idle_fraction(sample_s: float = SAMPLE_S) -> float | None:
    """Share of all CPU time that was idle (idle + iowait) over `sample_s`, or None."""
    def read() -> tuple[int, int]:
        with open("/proc/stat") as stat:
            fields = [int(x) for x in stat.readline().split()[1:]]
        return sum(fields), fields[3] + fields[4]

    try:
        total0, idle0 = read()
        time.sleep(sample_s)
        total1, idle1 = read()
    except (OSError, ValueError, IndexError):
        return None
    return (idle1 - idle0) / (total1 - total0) if total1 > total0 else None


def jobs(cores: int, idle: float | None) -> int:
    """Test processes for `cores` cores whose idle share is `idle` (None: unknown)."""
    extra = 1 if idle is not None and idle > 0.5 else 0
    return max(1, min(MAX_JOBS, cores + extra))


def cores() -> int:
    """The cores this process may run on (its affinity), like `nproc`."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


if __name__ == "__main__":
    print(jobs(cores(), idle_fraction()))
