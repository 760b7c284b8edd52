"""The chaos proxy's sockets (`gcs.sim.proxy.ChaosProxy`): a proxy that cannot open one of
its ports closes the ones it had opened before raising."""

from __future__ import annotations

import asyncio
import os
import socket

import pytest

from gcs.sim.ports import free_udp_base
from gcs.sim.proxy import ChaosProxy


def _open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def test_a_port_taken_leaves_no_socket_open() -> None:
    """Vehicle 1's port is taken: start raises, vehicle 0's two sockets are closed again
    (its port can be bound at once, and the process holds as many descriptors as before)."""
    base = free_udp_base(range(3))
    station = free_udp_base(range(3))
    taken = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    taken.bind(("127.0.0.1", base + 1))

    async def main() -> None:
        before = _open_fds()
        proxy = ChaosProxy([station + i for i in range(3)], base)
        with pytest.raises(OSError):
            await proxy.start()
        await asyncio.sleep(0.01)  # a transport closes its socket on the loop's next turn
        assert _open_fds() == before
        free = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        free.bind(("127.0.0.1", base))  # vehicle 0's port was given back
        free.close()

    try:
        asyncio.run(main())
    finally:
        taken.close()
