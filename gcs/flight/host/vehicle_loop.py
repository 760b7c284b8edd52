"""The thread that talks to vehicles: its own asyncio loop, apart from the caller's.

`VehicleLoop` runs one daemon thread ("fleetplan-vehicles") with its own event loop. The
flight executor (streamer, links, monitors, recorder) and the in-process mock vehicles run
there, so whatever the caller's loop does (REST handlers, exports, event streams, journal
writes, a blocking call) cannot delay a setpoint tick. The caller reaches it through `call`
(a coroutine there, awaited here), `run` (a function there) and `post` (fire and forget).

While a `VehicleLoop` runs, the interpreter's GIL switch interval is `SWITCH_INTERVAL_S`
(1 ms, Python's default is 5 ms): a thread that holds the GIL running Python code hands it
over after that long, so the vehicle thread waits at most about 1 ms for it at each wake-up.
A C extension that holds the GIL without releasing it (one large orjson dump) still delays it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import sys
import threading
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar

from gcs.errors import VehicleLoopStopped
from gcs.flight.timeline.realtime import enter_realtime

__all__ = ["SWITCH_INTERVAL_S", "VehicleLoop"]

log = logging.getLogger(__name__)

T = TypeVar("T")

#: The GIL switch interval while a vehicle loop runs (s).
SWITCH_INTERVAL_S = 0.001
#: How long `start` waits for the thread's loop to run (s).
START_TIMEOUT_S = 10.0

_switch_lock = threading.Lock()
_switch_users = 0
_switch_saved = 0.005


class VehicleLoop:
    """A daemon thread running its own asyncio loop for everything that talks to vehicles."""

    def __init__(self, name: str = "fleetplan-vehicles", *, realtime: bool = False) -> None:
        self.name = name
        self.realtime = realtime
        """Run the thread at SCHED_RR priority 1 (Linux; refused without root or
        CAP_SYS_NICE: logged, never fatal); see `scheduling`."""
        self.scheduling = "ordinary"
        """The thread's scheduling as set: ordinary, SCHED_RR 1, or why real-time was
        refused."""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._pending: set[concurrent.futures.Future[Any]] = set()
        self._pending_lock = threading.Lock()
        self._switch_held = False
        self._stop_posted = False

    # ------------------------------------------------------------------ lifecycle

    @property
    def alive(self) -> bool:
        """The thread and its loop are running."""
        return self._thread is not None and self._thread.is_alive() and self._ready.is_set()

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        """The thread's event loop; VehicleLoopStopped unless running."""
        if self._loop is None or not self.alive:
            raise VehicleLoopStopped("the vehicle loop is not running")
        return self._loop

    def start(self) -> None:
        """Start the thread and return once its loop runs."""
        if self._thread is not None:
            raise RuntimeError("a VehicleLoop starts once")
        self._hold_switch_interval()
        self._thread = threading.Thread(target=self._main, name=self.name, daemon=True)
        self._thread.start()
        if not self._ready.wait(START_TIMEOUT_S):
            raise VehicleLoopStopped("the vehicle loop did not start")

    def stop(self, timeout: float = 10.0) -> None:
        """Cancel what still runs there, stop the loop and join the thread (blocking: call it
        from a thread, e.g. ``await asyncio.to_thread(loop.stop)``)."""
        loop, thread = self._loop, self._thread
        if loop is not None and thread is not None and thread.is_alive():
            if self._ready.is_set() and not self._stop_posted:
                # once only: a second stop would cut short the tasks' cleanup (`_main`)
                self._stop_posted = True
                with contextlib.suppress(RuntimeError):  # closed meanwhile
                    loop.call_soon_threadsafe(loop.stop)
            thread.join(timeout)
        self._release_switch_interval()

    def _main(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        if self.realtime:
            self._enter_realtime()
        loop.call_soon(self._ready.set)
        try:
            loop.run_forever()
        except BaseException:  # a callback raised out of the loop: the thread ends
            log.exception("the vehicle loop %s ended on an error", self.name)
        finally:
            self._ready.clear()
            self._fail_pending()
            try:
                _cancel_all(loop)
            except BaseException:
                log.exception("the vehicle loop %s could not finish its tasks", self.name)
            loop.close()

    def _enter_realtime(self) -> None:
        """SCHED_RR 1 for this thread (`gcs.flight.timeline.realtime`), or a warning saying
        why not."""
        scheduling = enter_realtime()
        self.scheduling = scheduling.text
        if not scheduling.granted:
            log.warning("vehicle loop: %s", scheduling.text)

    def _fail_pending(self) -> None:
        """The thread is ending: every caller still waiting gets VehicleLoopStopped."""
        with self._pending_lock:
            pending, self._pending = self._pending, set()
        for future in pending:
            with contextlib.suppress(concurrent.futures.InvalidStateError, RuntimeError):
                if not future.done() and future.set_running_or_notify_cancel():
                    future.set_exception(VehicleLoopStopped(
                        "the vehicle loop stopped before this finished"))

    # ------------------------------------------------------------------ calls

    def on_loop(self) -> bool:
        """The caller runs on this loop's thread."""
        return threading.current_thread() is self._thread

    def submit(self, factory: Callable[[], Awaitable[T]]) -> concurrent.futures.Future[T]:
        """Run the coroutine `factory()` makes on the vehicle loop; its concurrent future
        (cancelling it cancels the coroutine; VehicleLoopStopped if the loop stops first)."""
        loop = self.loop
        result: concurrent.futures.Future[T] = concurrent.futures.Future()
        task: list[asyncio.Task[T]] = []

        async def body() -> T:
            return await factory()

        def finished(done: asyncio.Task[T]) -> None:
            if result.done() or not result.set_running_or_notify_cancel():
                return  # the caller cancelled it, or the loop stopped first
            if done.cancelled():
                result.set_exception(VehicleLoopStopped("cancelled on the vehicle loop"))
            elif (error := done.exception()) is not None:
                result.set_exception(error)
            else:
                result.set_result(done.result())

        def begin() -> None:
            if result.done():  # cancelled before it began
                return
            task.append(loop.create_task(body()))
            task[0].add_done_callback(finished)

        def cancel_there(future: concurrent.futures.Future[T]) -> None:
            if future.cancelled():
                with contextlib.suppress(RuntimeError):  # the loop has closed
                    loop.call_soon_threadsafe(lambda: task and task[0].cancel())
            self._forget(future)

        with self._pending_lock:
            self._pending.add(result)
        result.add_done_callback(cancel_there)
        loop.call_soon_threadsafe(begin)
        if not self.alive:  # the thread ended between the check and the submit
            self._fail_pending()
        return result

    async def call(self, factory: Callable[[], Awaitable[T]]) -> T:
        """Run the coroutine `factory()` makes on the vehicle loop and await its result here
        (its exception is raised here; cancelling the caller cancels it there)."""
        if self.on_loop():
            return await factory()
        return await asyncio.wrap_future(self.submit(factory))

    async def run(self, fn: Callable[[], T]) -> T:
        """Run the function `fn` on the vehicle loop and await its result here."""

        async def body() -> T:
            return fn()

        return await self.call(body)

    def post(self, fn: Callable[[], Any]) -> None:
        """Run `fn` on the vehicle loop soon, without waiting for it."""
        self.loop.call_soon_threadsafe(fn)

    def _forget(self, future: concurrent.futures.Future[Any]) -> None:
        with self._pending_lock:
            self._pending.discard(future)

    # ------------------------------------------------------------------ GIL switch interval

    def _hold_switch_interval(self) -> None:
        global _switch_users, _switch_saved
        with _switch_lock:
            if _switch_users == 0:
                _switch_saved = sys.getswitchinterval()
                sys.setswitchinterval(min(_switch_saved, SWITCH_INTERVAL_S))
            _switch_users += 1
        self._switch_held = True

    def _release_switch_interval(self) -> None:
        global _switch_users
        if not self._switch_held:
            return
        self._switch_held = False
        with _switch_lock:
            _switch_users -= 1
            if _switch_users == 0:
                sys.setswitchinterval(_switch_saved)


def _cancel_all(loop: asyncio.AbstractEventLoop) -> None:
    """Cancel the loop's remaining tasks and let them run their cleanup."""
    tasks = [t for t in asyncio.all_tasks(loop) if not t.done()]
    for task in tasks:
        task.cancel()
    if tasks:
        loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
    loop.run_until_complete(loop.shutdown_asyncgens())
