"""The control socket of `fleetplan fly --control PATH`: a running flight takes commands.

A unix-domain socket, made with mode 0600 (only its owner may connect) and removed when the
flight ends. One request per connection: the client sends one JSON object on one line and
reads one JSON line back. Requests:

- ``{"command": "replan", "goals": {...}, "drop": [...], "drop_action": "land"|"hold"}``
  (the body of POST /api/flights/{id}/replan, `gcs.replan_request`) -> ``{"ok": true,
  "replan": {...}}``, the replan object (status planning; its outcome follows as events);
- ``{"command": "pause"}`` / ``{"command": "resume"}`` -> ``{"ok": true, "flight_time": t}``;
- ``{"command": "abort", "action": "land"|"hold"}`` -> ``{"ok": true}``.

A refusal is ``{"ok": false, "error": {"type", "field", "reason"}}``: StateConflict (nothing
flying, paused, a replan already running), InvalidRequest or another FieldError naming the
field. `request` is the client's side (`fleetplan replan`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import socket
import stat
from pathlib import Path
from typing import Any, Protocol

from gcs.documents import ReplanDocument
from gcs.errors import GcsError, InvalidRequest
from gcs.phases import ABORT_ACTIONS
from gcs.replan_request import parse
from planner.errors import FieldError

__all__ = ["COMMANDS", "REQUEST_BYTES_MAX", "ControlServer", "ControlledFlight", "request"]

#: The commands a control socket takes.
COMMANDS = ("replan", "pause", "resume", "abort")
#: Longest request line (bytes): a replan of every vehicle of a large fleet fits.
REQUEST_BYTES_MAX = 2_000_000
#: How long a connection may take to send its request, and a client waits for the answer (s).
READ_TIMEOUT_S = 10.0
#: The reason given with every abort over the socket.
ABORT_REASON = "operator abort (control socket)"


class ControlledFlight(Protocol):
    """What the socket drives: `gcs.flight.host.flight_handle.FlightHandle`'s commands."""

    async def replan(self, goals: dict[str, list[float]] | None, drop: list[str],
                     drop_action: str, reason: str) -> ReplanDocument: ...
    async def pause(self) -> float: ...
    async def resume(self) -> float: ...
    async def abort(self, action: str = "land", reason: str = "operator abort") -> None: ...


class ControlServer:
    """The socket at `path`, serving `flight` until `close`; see the module."""

    def __init__(self, path: str | Path, flight: ControlledFlight, vehicles: int) -> None:
        """`vehicles`: how many the plan flies (a replan naming more entries is refused)."""
        self.path = Path(path)
        self._flight = flight
        self._vehicles = vehicles
        self._server: asyncio.AbstractServer | None = None
        self._inode: int | None = None

    async def start(self) -> None:
        """Make the socket (mode 0600; a stale socket left by a killed run is replaced).
        OSError when PATH is something else, or another flight listens on it."""
        _clear_stale(self.path)
        old = os.umask(0o177)  # made 0600 at once: nobody else can connect, not even briefly
        try:
            self._server = await asyncio.start_unix_server(
                self._serve, path=str(self.path), limit=REQUEST_BYTES_MAX)
        finally:
            os.umask(old)
        os.chmod(self.path, 0o600)
        self._inode = self.path.stat().st_ino

    async def close(self) -> None:
        """Stop listening and remove the socket (unless another process replaced it)."""
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)
            self._server = None
        with contextlib.suppress(OSError):
            if self._inode is not None and self.path.stat().st_ino == self._inode:
                self.path.unlink()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            try:
                line = await asyncio.wait_for(reader.readline(), READ_TIMEOUT_S)
                answer = await self.answer(json.loads(line))
            except (ValueError, asyncio.LimitOverrunError) as exc:
                answer = _refusal(InvalidRequest("body", f"not one JSON line: {exc}"))
            except TimeoutError:
                answer = _refusal(InvalidRequest("body", "no request within "
                                                         f"{READ_TIMEOUT_S:g} s"))
            writer.write(json.dumps(answer).encode() + b"\n")
            await writer.drain()
        except (ConnectionError, OSError):
            pass  # the client went away: nothing to answer
        finally:
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()

    async def answer(self, document: Any) -> dict[str, Any]:
        """The answer to one decoded request (a refusal names the field)."""
        try:
            if not isinstance(document, dict):
                raise InvalidRequest("body", "must be a JSON object")
            body = dict(document)
            command = body.pop("command", None)
            if command not in COMMANDS:
                raise InvalidRequest("command", f"must be one of {', '.join(COMMANDS)}, "
                                                f"got {command!r}")
            if command == "replan":
                checked = parse(body, self._vehicles, "the plan's {max} vehicles")
                replan = await self._flight.replan(
                    checked.goals, list(checked.drop or ()), checked.drop_action,
                    "operator (control socket)")
                return {"ok": True, "replan": replan}
            if command in ("pause", "resume"):
                _no_more(body)
                run = self._flight.pause if command == "pause" else self._flight.resume
                return {"ok": True, "flight_time": await run()}
            action = body.pop("action", "land")
            _no_more(body)
            if action not in ABORT_ACTIONS:
                raise InvalidRequest("action", f"must be one of {', '.join(ABORT_ACTIONS)}, "
                                               f"got {action!r}")
            await self._flight.abort(action, ABORT_REASON)
            return {"ok": True}
        except (GcsError, FieldError) as exc:
            return _refusal(exc)


def _no_more(body: dict[str, Any]) -> None:
    """InvalidRequest naming a field the command does not take."""
    if body:
        raise InvalidRequest(next(iter(body)), "is not a field of this command")


def _refusal(error: Exception) -> dict[str, Any]:
    field = error.field if isinstance(error, FieldError) else None
    reason = error.reason if isinstance(error, FieldError) else str(error)
    return {"ok": False, "error": {"type": type(error).__name__, "field": field,
                                   "reason": reason}}


def _clear_stale(path: Path) -> None:
    """Remove a socket no flight listens on any more; OSError for anything else at `path`."""
    try:
        mode = path.lstat().st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISSOCK(mode):
        raise OSError(f"{path} exists and is not a socket: choose another --control path")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.connect(str(path))
    except OSError:
        path.unlink()  # stale: left by a run that was killed
        return
    finally:
        probe.close()
    raise OSError(f"{path}: another flight's control socket listens there")


async def request(path: str | Path, document: dict[str, Any]) -> dict[str, Any]:
    """Send one request to the control socket at `path`; its answer. OSError when nothing
    listens there; ValueError for an answer that is not JSON."""
    reader, writer = await asyncio.open_unix_connection(str(path), limit=REQUEST_BYTES_MAX)
    try:
        writer.write(json.dumps(document).encode() + b"\n")
        await writer.drain()
        line = await asyncio.wait_for(reader.readline(), READ_TIMEOUT_S)
    finally:
        writer.close()
        with contextlib.suppress(Exception):
            await writer.wait_closed()
    answer = json.loads(line)
    if not isinstance(answer, dict):
        raise ValueError(f"the control socket answered {line[:80]!r}")
    return answer
