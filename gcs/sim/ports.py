"""The mock fleet's port rule, and free local UDP ports for mock fleets.

A mock fleet on base port B is laid out like PX4 SITL on `gcs.autopilot.px4.OFFBOARD_GCS_BASE_PORT`:
vehicle i sends its offboard link to B + i and listens on B + `LISTEN_OFFSET` + i (PX4:
`OFFBOARD_GCS_BASE_PORT` + i / `OFFBOARD_VEHICLE_BASE_PORT` + i). A fleet of more than
`LISTEN_OFFSET` vehicles listens right after its own GCS block instead (B + count + i), where
the two blocks cannot overlap.

Tests, benchmarks and demos run mock vehicles while other fleets (PX4 SITL, another test
suite) may be running on the same machine; a random base far from PX4's ports that binds
cleanly right now avoids collisions.
"""

from __future__ import annotations

import random
import socket
from collections.abc import Iterable

from gcs.autopilot import px4

__all__ = ["LISTEN_OFFSET", "block_free", "free_mock_fleet_ports", "free_udp_base",
           "listen_offset", "mock_fleet_ports", "mock_port_offsets"]

#: Vehicle i of a mock fleet on base B listens on B + LISTEN_OFFSET + i (PX4 SITL's offset, 40).
LISTEN_OFFSET = px4.OFFBOARD_VEHICLE_BASE_PORT - px4.OFFBOARD_GCS_BASE_PORT


def listen_offset(count: int) -> int:
    """Where a fleet of `count` vehicles listens, from its base: PX4 SITL's `LISTEN_OFFSET`,
    or past the GCS block of a larger fleet."""
    return max(LISTEN_OFFSET, count)


def mock_port_offsets(count: int) -> list[int]:
    """Offsets from the base of every UDP port a mock fleet of `count` vehicles uses."""
    listen = listen_offset(count)
    return [*range(count), *range(listen, listen + count)]


def mock_fleet_ports(base: int, count: int) -> dict[str, int]:
    """`MockFleet` keyword arguments for a fleet of `count` vehicles on base port `base` (the
    rule above; any count up to `LISTEN_OFFSET` gives PX4 SITL's layout)."""
    return {"gcs_base_port": base, "listen_base_port": base + listen_offset(count)}


def free_mock_fleet_ports(count: int) -> dict[str, int]:
    """`mock_fleet_ports` for `count` vehicles on a base whose every port is free now."""
    return mock_fleet_ports(free_udp_base(mock_port_offsets(count)), count)


def block_free(base: int, offsets: Iterable[int], host: str = "127.0.0.1") -> bool:
    """Is every UDP port `base` + offset free on `host` right now (each binds)?"""
    sockets: list[socket.socket] = []
    try:
        for offset in offsets:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sockets.append(sock)
            sock.bind((host, base + offset))
        return True
    except OSError:
        return False
    finally:
        for sock in sockets:
            sock.close()


def free_udp_base(offsets: Iterable[int], *, host: str = "127.0.0.1", low: int = 20_000,
                  high: int = 60_000, attempts: int = 200) -> int:
    """A base port B such that every UDP port B + offset is free on `host` right now."""
    spread = list(offsets)
    top = max(spread, default=0)
    for _ in range(attempts):
        base = random.randrange(low, high - top)
        if block_free(base, spread, host):
            return base
    raise OSError(f"no free block of UDP ports found on {host} in {attempts} tries")
