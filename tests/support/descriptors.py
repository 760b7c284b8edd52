"""The pipe descriptors a process holds: what a race's arms (`planner.methods.race`) open and
must close. Other descriptors (sockets, files) belong to whatever else runs in a test worker."""

from __future__ import annotations

import os

__all__ = ["pipes"]


def pipes() -> set[int]:
    """The pipe descriptors open in this process."""
    out = set()
    for name in os.listdir("/proc/self/fd"):
        try:
            if os.readlink(f"/proc/self/fd/{name}").startswith("pipe:"):
                out.add(int(name))
        except OSError:
            continue  # the listing's own descriptor, closed meanwhile
    return out
