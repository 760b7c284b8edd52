"""A bare pymavlink ground station for the mock's protocol tests: one UDP socket, every
message it receives in a queue, nothing of `gcs.flight` (so the mock is checked against plain
MAVLink, not against our own link)."""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable
from typing import Any

from gcs.wire import Datagrams, mavlink
from tests.support.waiting import until

__all__ = ["MavClient"]


class MavClient:
    """A GCS (system 255) bound to `bind` that talks to one mock vehicle at `vehicle`."""

    def __init__(self, bind: tuple[str, int], vehicle: tuple[str, int],
                 system_id: int = 1) -> None:
        self.bind = bind
        self.vehicle = vehicle
        self.system_id = system_id
        self.mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.received: list[tuple[float, Any]] = []
        """(monotonic time, message) of every message received, in order."""
        self.raw: list[bytes] = []
        """Every datagram received (for messages pymavlink's dialect lacks)."""
        self._transport: asyncio.DatagramTransport | None = None

    async def __aenter__(self) -> MavClient:
        loop = asyncio.get_running_loop()
        self._transport, _ = await loop.create_datagram_endpoint(
            lambda: Datagrams(self._datagram), local_addr=self.bind)
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self._transport is not None:
            self._transport.close()

    def _datagram(self, data: bytes, _address: Any) -> None:
        self.raw.append(data)
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        for msg in parser.parse_buffer(data) or []:
            if msg.get_type() != "BAD_DATA":
                self.received.append((time.monotonic(), msg))

    def send(self, msg: Any) -> None:
        assert self._transport is not None
        self._transport.sendto(msg.pack(self.mav), self.vehicle)

    def heartbeat(self) -> None:
        self.send(self.mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                            0, 0, 0))

    def command(self, command: int, *params: float) -> None:
        p = [*params, *([0.0] * (7 - len(params)))]
        self.send(self.mav.command_long_encode(self.system_id, 1, command, 0, *p))

    def set_param(self, name: str, value: float, kind: int = mavlink.MAV_PARAM_TYPE_REAL32,
                  field: float | None = None) -> None:
        """PARAM_SET; `field` overrides the float sent (byte-wise INT32 values)."""
        self.send(self.mav.param_set_encode(self.system_id, 1, name.encode(),
                                            value if field is None else field, kind))

    def messages(self, kind: str, since: float = -math.inf) -> list[Any]:
        return [m for t, m in self.received if t >= since and m.get_type() == kind]

    def texts(self) -> list[str]:
        return [m.text for m in self.messages("STATUSTEXT")]

    async def wait(self, kind: str, where: Callable[[Any], bool] = lambda _m: True,
                   timeout: float = 3.0, since: float | None = None) -> Any:
        """The first `kind` message since `since` (default: now) meeting `where`."""
        start = time.monotonic() if since is None else since
        return await until(lambda: next((m for t, m in self.received if t >= start
                                         and m.get_type() == kind and where(m)), None),
                           f"a {kind}", timeout, poll=0.01)

    async def ack(self, command: int, timeout: float = 3.0, since: float | None = None) -> int:
        """The result of the first COMMAND_ACK of `command` since `since`."""
        msg = await self.wait("COMMAND_ACK", lambda m: m.command == command, timeout, since)
        return int(msg.result)
