"""Finding free local UDP ports for mock fleets, away from PX4's fixed 14540-14600 range.

Tests, benchmarks and demos run mock vehicles while other fleets (PX4 SITL, another test
suite) may be running on the same machine; a random base far from PX4's ports that binds
cleanly right now avoids collisions.
"""

from __future__ import annotations

import random
import socket
from collections.abc import Iterable

__all__ = ["free_udp_base"]


def free_udp_base(offsets: Iterable[int], *, host: str = "127.0.0.1", low: int = 20_000,
                  high: int = 60_000, attempts: int = 200) -> int:
    """A base port B such that every UDP port B + offset is free on `host` right now."""
    spread = list(offsets)
    top = max(spread, default=0)
    for _ in range(attempts):
        base = random.randrange(low, high - top)
        sockets: list[socket.socket] = []
        try:
            for offset in spread:
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                sockets.append(sock)
                sock.bind((host, base + offset))
            return base
        except OSError:
            continue
        finally:
            for sock in sockets:
                sock.close()
    raise OSError(f"no free block of UDP ports found on {host} in {attempts} tries")
