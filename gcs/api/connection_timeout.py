"""Connections that never complete a request are closed: uvicorn's h11 protocol with a
request deadline.

uvicorn closes a keep-alive connection that stays idle after a response, but it waits for
ever on a connection that sends nothing, or a request head or body a byte at a time. Here a
request must arrive in full (head and body) within `request_timeout_s` of its first byte, or
of the connection opening for the first request; otherwise the connection is closed with no
answer. A request already received runs as long as its handler needs (event streams too).
"""

from __future__ import annotations

import asyncio
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

__all__ = ["request_deadline_protocol"]


class _DeadlineH11Protocol(H11Protocol):
    """H11Protocol whose requests must arrive within `request_timeout_s`."""

    request_timeout_s: float = 10.0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._deadline: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()

    def data_received(self, data: bytes) -> None:
        if self.conn.their_state is h11.IDLE:
            self._arm()  # a request starts: it has the whole deadline
        super().data_received(data)
        if self.conn.their_state not in (h11.IDLE, h11.SEND_BODY):
            self._disarm()  # received in full (or the connection is done)

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def _arm(self) -> None:
        if self._deadline is None:
            self._deadline = self.loop.call_later(self.request_timeout_s, self._expire)

    def _disarm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def _expire(self) -> None:
        """The request is still incomplete: close the connection. A handler waiting on the
        body that does not come sees the client disconnect."""
        self._deadline = None
        if self.conn.their_state in (h11.IDLE, h11.SEND_BODY) and not self.transport.is_closing():
            self.transport.close()


def request_deadline_protocol(request_timeout_s: float) -> type[H11Protocol]:
    """uvicorn's ``http`` protocol class closing connections whose request takes longer than
    `request_timeout_s` to arrive."""
    return type("DeadlineH11Protocol", (_DeadlineH11Protocol,),
                {"request_timeout_s": request_timeout_s})
