"""The process that talks to vehicles: a child process of its own, apart from its caller.

`VehicleProcess` starts one child process that runs a `VehicleLoop` (its vehicle thread, at
real-time priority when asked) and builds a *host* there: the object that owns the links,
the mocks and the flights (for the service, `gcs.service.vehicle_host.FleetHost`). The caller
reaches the host through `call` (a public method by name, its arguments and answer pickled
over a private pipe) and hears from it through notices (`on_notice`: events, snapshots).

A process, not a thread, because two threads of one interpreter share its lock: a REST
handler, an export or an event stream holding the GIL delays a setpoint tick by as long.
Across processes the caller can be busy, blocked or starved without costing the flight a tick;
only the machine's cores are shared, and real-time priority settles those.

In the child the vehicle thread never waits on the pipe: answers and notices are queued and
sent by a sender thread, and requests are read by the child's main thread. If the caller's
process ends (its end of the pipe closes) or the child is sent SIGTERM, the host's `close` runs
(a flight under way lands) before the child exits; SIGINT is left to the caller, which tells
the host what to do.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import inspect
import itertools
import logging
import multiprocessing
import queue
import signal
import threading
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from gcs.errors import GcsError, VehicleLoopStopped
from gcs.flight.host.vehicle_loop import VehicleLoop
from gcs.flight.timeline.realtime import settle_heap

__all__ = ["HostContext", "VehicleProcess"]

log = logging.getLogger(__name__)

#: How long `start` waits for the child's host to be built (s): a spawned interpreter imports
#: numpy, pymavlink and the rest first.
START_TIMEOUT_S = 60.0
#: How long the child gives its host's `close` (landing a flight under way) before it exits (s).
CLOSE_TIMEOUT_S = 90.0
#: How long `stop` waits for the child to exit after asking, before terminating it (s).
STOP_GRACE_S = CLOSE_TIMEOUT_S + 10.0

#: What the host calls to tell the caller something: notify(kind, data).
Notify = Callable[[str, Any], None]


@dataclass(frozen=True)
class HostContext:
    """What a host is built with in the child: its vehicle loop and how to notify."""

    vehicles: VehicleLoop
    notify: Notify


class _Stop(Exception):
    """SIGTERM in the child: leave the request loop and close the host."""


class VehicleProcess:
    """A child process hosting the vehicle side; see the module."""

    def __init__(self, factory: Callable[[HostContext], Any], *,
                 name: str = "fleetplan-vehicles", realtime: bool = False,
                 on_notice: Callable[[str, Any], None] | None = None,
                 preload: tuple[str, ...] = ()) -> None:
        """`factory(context)` builds the host in the child: a picklable callable (a class or a
        `functools.partial` of one). `preload` names modules the fork server imports once, so
        each child starts in a fraction of a second."""
        self.name = name
        self.realtime = realtime
        self.scheduling = "ordinary"
        """The child's vehicle thread's scheduling, as `VehicleLoop.scheduling` (once
        started)."""
        self._factory = factory
        self._on_notice = on_notice
        self._preload = preload
        self._process: Any = None
        self._conn: Connection | None = None
        self._caller: asyncio.AbstractEventLoop | None = None
        self._pending: dict[int, asyncio.Future[Any]] = {}
        self._ids = itertools.count(1)
        self._send_lock = threading.Lock()
        self._ready: asyncio.Future[str] | None = None
        self._ended = False

    # ------------------------------------------------------------------ lifecycle

    @property
    def alive(self) -> bool:
        """The child runs and answers."""
        return (self._process is not None and not self._ended and self._ready is not None
                and self._ready.done() and not self._ready.exception()
                and self._process.is_alive())

    @property
    def pid(self) -> int | None:
        """The child's process id, once started."""
        return None if self._process is None else self._process.pid

    async def start(self) -> None:
        """Start the child and return once its host is built (its error raised here)."""
        if self._process is not None:
            raise RuntimeError("a VehicleProcess starts once")
        self._caller = asyncio.get_running_loop()
        self._ready = self._caller.create_future()
        context = multiprocessing.get_context("forkserver")
        if self._preload:
            context.set_forkserver_preload(list(self._preload))
        mine, theirs = context.Pipe(duplex=True)
        self._conn = mine
        self._process = context.Process(
            target=_child_main, args=(theirs, self._factory, self.name, self.realtime),
            name=self.name, daemon=True)
        await asyncio.to_thread(self._process.start)
        theirs.close()
        threading.Thread(target=self._read, name=f"{self.name}-reader", daemon=True).start()
        try:
            self.scheduling = await asyncio.wait_for(asyncio.shield(self._ready),
                                                     START_TIMEOUT_S)
        except TimeoutError:
            await self.stop()
            raise VehicleLoopStopped("the vehicle process did not start") from None

    async def stop(self) -> None:
        """Ask the child to close its host and exit; terminate it if it does not in time."""
        process = self._process
        if process is None:
            return
        if process.is_alive():
            with contextlib.suppress(OSError, ValueError):
                self._send(("stop",))
            await asyncio.to_thread(process.join, STOP_GRACE_S)
            if process.is_alive():
                log.error("the vehicle process did not exit: terminating it")
                process.terminate()
                await asyncio.to_thread(process.join, 5.0)
        if self._conn is not None:
            self._conn.close()

    # ------------------------------------------------------------------ calls

    async def call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """The host's `method(*args, **kwargs)` run on the child's vehicle loop (awaited there
        if it is a coroutine); its answer, or its exception raised here. VehicleLoopStopped
        when the child is not running or ends first."""
        if not self.alive or self._caller is None:
            raise VehicleLoopStopped("the vehicle process is not running")
        call_id = next(self._ids)
        answer: asyncio.Future[Any] = self._caller.create_future()
        self._pending[call_id] = answer
        try:
            try:
                self._send(("call", call_id, method, args, kwargs))
            except (OSError, ValueError) as exc:  # the pipe closed under us
                raise VehicleLoopStopped(
                    f"the vehicle process is not running ({exc})") from None
            return await answer
        finally:
            self._pending.pop(call_id, None)

    def _send(self, message: tuple[Any, ...]) -> None:
        assert self._conn is not None
        with self._send_lock:
            self._conn.send(message)

    # ------------------------------------------------------------------ what the child says

    def _read(self) -> None:
        """Reader thread: hand every message to the caller's loop, then the end."""
        assert self._conn is not None and self._caller is not None
        while True:
            try:
                message = self._conn.recv()
            except (EOFError, OSError):
                break
            except Exception:  # a message that does not unpickle here: its caller would
                # wait for ever, so the process is given up (its callers fail at once)
                log.exception("unreadable message from the vehicle process: giving it up")
                self._process.terminate()  # SIGTERM: the host lands what flies, then exits
                break
            if not self._to_caller(self._dispatch, message):
                return
        self._to_caller(self._end)

    def _to_caller(self, fn: Callable[..., None], *args: Any) -> bool:
        assert self._caller is not None
        try:
            self._caller.call_soon_threadsafe(fn, *args)
            return True
        except RuntimeError:  # the caller's loop has closed
            return False

    def _dispatch(self, message: tuple[Any, ...]) -> None:
        kind = message[0]
        if kind == "reply":
            _, call_id, ok, value = message
            answer = self._pending.get(call_id)
            if answer is not None and not answer.done():
                if ok:
                    answer.set_result(value)
                else:
                    answer.set_exception(value)
        elif kind == "notice":
            if self._on_notice is not None:
                try:
                    self._on_notice(message[1], message[2])
                except Exception:
                    log.exception("a notice from the vehicle process could not be handled")
        elif kind == "ready":
            if self._ready is not None and not self._ready.done():
                self._ready.set_result(message[1])
        elif kind == "failed" and self._ready is not None and not self._ready.done():
            self._ready.set_exception(message[1])

    def _end(self) -> None:
        """The child's end of the pipe closed (or its messages cannot be read): every waiting
        call fails, and the caller is told (notice ``ended``, also after a stop it asked
        for)."""
        self._ended = True
        code = None if self._process is None else self._process.exitcode
        why = f"the vehicle process ended (exit code {code})"
        for answer in list(self._pending.values()):
            if not answer.done():
                answer.set_exception(VehicleLoopStopped(why))
        if self._ready is not None and not self._ready.done():
            self._ready.set_exception(VehicleLoopStopped(why))
        if self._on_notice is not None:
            with contextlib.suppress(Exception):
                self._on_notice("ended", {"reason": why})


# ---------------------------------------------------------------------- in the child


def _child_main(conn: Connection, factory: Callable[[HostContext], Any], name: str,
                realtime: bool) -> None:
    """The child: build the host on a vehicle loop, serve calls until told to stop or the
    caller is gone, then close the host."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the caller's to handle

    def stop_on_term(signum: int, frame: Any) -> None:
        raise _Stop

    signal.signal(signal.SIGTERM, stop_on_term)
    outbox: queue.SimpleQueue[tuple[Any, ...] | None] = queue.SimpleQueue()
    sender = threading.Thread(target=_send_all, args=(conn, outbox), name=f"{name}-sender",
                              daemon=True)
    sender.start()
    vehicles = VehicleLoop(name=name, realtime=realtime)
    try:
        vehicles.start()
        context = HostContext(vehicles, lambda kind, data: outbox.put(("notice", kind, data)))
        host = vehicles.submit(functools.partial(_build, factory, context)).result()
    except BaseException as exc:
        outbox.put(("failed", _portable(exc)))
        outbox.put(None)
        sender.join(5.0)
        vehicles.stop()
        return
    outbox.put(("ready", vehicles.scheduling))
    settle_heap()  # the imported code and the host: never walked by a collection again
    try:
        _serve(conn, host, vehicles, outbox)
    except _Stop:
        pass
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the close below is not cut short
        with contextlib.suppress(BaseException):
            vehicles.submit(functools.partial(_invoke, host, "close", (), {})).result(
                CLOSE_TIMEOUT_S)
        vehicles.stop()
        outbox.put(None)
        sender.join(5.0)


def _serve(conn: Connection, host: Any, vehicles: VehicleLoop,
           outbox: queue.SimpleQueue[tuple[Any, ...] | None]) -> None:
    """Read calls until ``stop`` or the caller's end closes; run each on the vehicle loop."""
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            log.warning("the vehicle process's caller is gone: closing")
            return
        if message[0] == "stop":
            return
        if message[0] != "call":
            continue
        _, call_id, method, args, kwargs = message
        if not isinstance(method, str) or method.startswith("_") or not callable(
                getattr(host, method, None)):
            outbox.put(("reply", call_id, False, GcsError(f"no host method {method!r}")))
            continue
        future = vehicles.submit(functools.partial(_invoke, host, method, args, kwargs))
        future.add_done_callback(functools.partial(_answer, outbox, call_id))


async def _build(factory: Callable[[HostContext], Any], context: HostContext) -> Any:
    host = factory(context)
    start = getattr(host, "start", None)
    if start is not None:
        started = start()
        if inspect.isawaitable(started):
            await started
    return host


async def _invoke(host: Any, method: str, args: tuple[Any, ...],
                  kwargs: dict[str, Any]) -> Any:
    result = getattr(host, method)(*args, **kwargs)
    if inspect.isawaitable(result):
        result = await result
    return result


def _answer(outbox: queue.SimpleQueue[tuple[Any, ...] | None], call_id: int,
            future: Any) -> None:
    if future.cancelled():
        outbox.put(("reply", call_id, False, VehicleLoopStopped("cancelled in the child")))
    elif (error := future.exception()) is not None:
        outbox.put(("reply", call_id, False, _portable(error)))
    else:
        outbox.put(("reply", call_id, True, future.result()))


def _portable(error: BaseException) -> BaseException:
    """`error` if it pickles, else a GcsError naming it (the caller must get an answer)."""
    import pickle

    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:
        return GcsError(f"{type(error).__name__}: {error}")


def _send_all(conn: Connection, outbox: queue.SimpleQueue[tuple[Any, ...] | None]) -> None:
    """Sender thread: send what is queued (an answer that does not pickle is sent as an
    error) until None, or the caller's end closes."""
    while (message := outbox.get()) is not None:
        try:
            conn.send(message)
        except (OSError, EOFError):
            return
        except Exception as exc:
            if message[0] == "reply":
                with contextlib.suppress(Exception):
                    conn.send(("reply", message[1], False, GcsError(
                        f"the vehicle process could not send its answer: {exc}")))
            else:
                log.exception("could not send %s to the caller", message[0])
