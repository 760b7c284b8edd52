"""Connections that never complete a request are closed; requests received in full (event
streams too) run as long as they need. uvicorn with the service's protocol class, on a
small ASGI app, with a 0.5 s request deadline."""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import uvicorn

from gcs.api.connection_timeout import request_deadline_protocol
from gcs.cli.serve_cmd import uvicorn_server
from gcs.service.settings import Settings
from tests.api.support import free_port
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

DEADLINE_S = 0.5
#: Longest any test waits for the server to act (a loose bound for a busy machine).
BOUND_S = 20.0


async def app(scope: dict[str, Any], receive: Any, send: Any) -> None:
    """/stream: three chunks over 1.5 s (longer than the deadline); anything else: the body
    length, once the whole body is read."""
    if scope["type"] != "http":
        return
    if scope["path"] == "/stream":
        await send({"type": "http.response.start", "status": 200, "headers": []})
        for n in range(3):
            await asyncio.sleep(0.5)
            await send({"type": "http.response.body", "body": f"chunk{n}\n".encode(),
                        "more_body": n < 2})
        return
    size = 0
    while True:
        message = await receive()
        if message["type"] == "http.disconnect":
            return
        size += len(message.get("body", b""))
        if not message.get("more_body"):
            break
    body = str(size).encode()
    await send({"type": "http.response.start", "status": 200,
                "headers": [(b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})


@pytest.fixture(scope="module")
def server() -> Iterator[int]:
    port = free_port()
    config = uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning",
                            http=request_deadline_protocol(DEADLINE_S), timeout_keep_alive=1)
    running = uvicorn.Server(config)
    thread = threading.Thread(target=running.run, daemon=True)
    thread.start()
    wait_for(lambda: running.started, "the server to start", timeout=BOUND_S, poll=0.02)
    yield port
    running.should_exit = True
    thread.join(10)


def _connect(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=BOUND_S)
    return sock


def _read_all(sock: socket.socket) -> bytes:
    """Everything the server sends until it closes the connection."""
    out = b""
    while chunk := sock.recv(4096):
        out += chunk
    return out


def _one_response(sock: socket.socket) -> bytes:
    """One response with a Content-Length, read in full (head and body)."""
    out = b""
    while b"\r\n\r\n" not in out:
        out += sock.recv(4096)
    head, _, body = out.partition(b"\r\n\r\n")
    length = int(head.lower().split(b"content-length: ")[1].split(b"\r\n")[0])
    while len(body) < length:
        body += sock.recv(4096)
    return head + b"\r\n\r\n" + body


def test_a_connection_that_sends_nothing_is_closed(server: int) -> None:
    with _connect(server) as sock:
        assert _read_all(sock) == b""  # closed, no answer


def test_a_request_head_sent_a_byte_at_a_time_is_closed(server: int) -> None:
    with _connect(server) as sock:
        head = b"GET /slow HTTP/1.1\r\nHost: x\r\nX-Padding: " + b"a" * 400
        started = time.monotonic()
        try:
            for byte in head:
                sock.send(bytes([byte]))
                time.sleep(0.01)
                assert time.monotonic() - started < BOUND_S  # bound
        except (BrokenPipeError, ConnectionResetError):
            pass  # closed while it was still sending: what is asked for
        assert _read_all(sock) == b""


def test_a_body_that_stops_coming_is_closed(server: int) -> None:
    with _connect(server) as sock:
        sock.sendall(b"POST /upload HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\n" +
                     b"x" * 10)
        assert _read_all(sock) == b""


def test_complete_requests_are_answered_and_kept_alive(server: int) -> None:
    with _connect(server) as sock:
        for body in (b"abc", b"abcdef"):
            sock.sendall(b"POST /upload HTTP/1.1\r\nHost: x\r\nContent-Length: "
                         + str(len(body)).encode() + b"\r\n\r\n" + body)
            answer = _one_response(sock)
            assert answer.startswith(b"HTTP/1.1 200") and answer.endswith(
                b"\r\n\r\n" + str(len(body)).encode())
            time.sleep(0.3)  # less than the idle timeout: the connection stays open


def test_a_response_longer_than_the_deadline_arrives_in_full(server: int) -> None:
    with _connect(server) as sock:
        sock.sendall(b"GET /stream HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        answer = _read_all(sock)
    assert answer.startswith(b"HTTP/1.1 200")
    assert b"chunk0" in answer and b"chunk2" in answer


def test_the_service_serves_with_the_settings_deadlines() -> None:
    settings = Settings(database_url="sqlite://", mock_vehicles=0, request_timeout_s=3.0,
                        idle_timeout_s=7.0)
    server = uvicorn_server(app, settings, "warning")
    assert server.config.http.request_timeout_s == 3.0
    assert server.config.timeout_keep_alive == 7
