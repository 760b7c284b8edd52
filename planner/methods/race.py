"""Run a few functions at once in forked child processes; the first acceptable result wins.

Each arm runs in a child made by a plain `os.fork` (not `multiprocessing`: it refuses to
start children from a daemonic process, which is what Dask's worker processes are), limited
to one BLAS thread so two arms share two cores without oversubscribing them. The child sends
length-prefixed pickles down a pipe: progress messages while it works, then its result. The
parent forwards progress as it arrives (from the calling thread, in arrival order), and as
soon as one arm's result is accepted it kills the others (SIGKILL) and reaps them; whatever
ends the race (a result, an exception from `progress`, Ctrl-C) kills and reaps every child
still running, so none is left behind as a zombie or holding memory. A child also dies with
the thread that forked it (Linux `PR_SET_PDEATHSIG`): a Dask worker restarted to stop its
task takes its arms with it. Without `os.fork` (not POSIX) the arms run one after another
in process, until one is accepted.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import selectors
import signal
import struct
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = ["ArmResult", "race"]

#: An arm: its name and the function it runs, given a `send(progress)` callable.
Arm = tuple[str, Callable[[Callable[[Any], None]], Any]]

_HEADER = struct.Struct("!Q")
_PROGRESS, _RESULT, _ERROR = "progress", "result", "error"
#: Linux prctl option: the signal a child gets when the thread that forked it ends.
_PR_SET_PDEATHSIG = 1
_READ_CHUNK = 1 << 20
#: Every race pipe end open in this process (of every race, in every thread), and the lock
#: under which pipes are made, forked with and closed (`_spawn`, `_close`).
_OPEN_FDS: set[int] = set()
_FDS_LOCK = threading.RLock()


@dataclass
class ArmResult:
    """What became of one arm: its result, or why it has none."""

    name: str
    value: Any = None
    error: str | None = None
    """Why the arm gave no result (an exception, a signal, cancelled)."""
    cancelled: bool = False
    """Killed because another arm's result was accepted first."""
    seconds: float = 0.0
    """Wall time from the race's start to the arm's end (s)."""


def race(arms: Sequence[Arm], accept: Callable[[Any], bool],
         progress: Callable[[Any], None] | None = None) -> list[ArmResult]:
    """Run `arms` at once; returns one `ArmResult` per arm, in the order given. Stops at the
    first result `accept` takes (the other arms cancelled), else when every arm ended.
    `progress` gets every progress message an arm sends, as `(arm name, message)`."""
    if not hasattr(os, "fork"):  # pragma: no cover - POSIX only
        return _one_by_one(arms, accept, progress)
    began = time.perf_counter()
    results = [ArmResult(name) for name, _ in arms]
    children: dict[int, _Child] = {}
    pools = _thread_pools()
    waiting = selectors.DefaultSelector()  # epoll: any fd number (select stops at 1024)
    try:
        for index, (name, fn) in enumerate(arms):
            try:
                child = _spawn(name, fn, index, pools)
            except OSError as exc:  # no process or pipe to be had: this arm cannot run
                results[index].error = f"could not start: {exc}"
                continue
            children[child.fd] = child
            waiting.register(child.fd, selectors.EVENT_READ)
        while children:
            for key, _ in waiting.select():
                fd = int(key.fd)
                child = children[fd]
                chunk = os.read(fd, _READ_CHUNK)
                if chunk:
                    child.buffer.extend(chunk)
                for kind, payload in child.messages():
                    if kind == _PROGRESS:
                        if progress is not None:
                            progress((child.name, payload))
                        continue
                    result = results[child.index]
                    result.seconds = time.perf_counter() - began
                    if kind == _RESULT:
                        result.value = payload
                        child.done = True
                        if accept(payload):
                            _end(children.values(), results, began, cancel=True)
                            children.clear()
                            return results
                    else:
                        result.error = payload
                        child.done = True
                if not chunk:  # the arm's pipe closed: it ended
                    waiting.unregister(fd)
                    _reap(child, results[child.index], began)
                    del children[fd]
        return results
    finally:
        waiting.close()
        _end(children.values(), results, began, cancel=False)


@dataclass
class _Child:
    name: str
    index: int
    pid: int
    fd: int
    buffer: bytearray
    done: bool = False

    def messages(self) -> list[tuple[str, Any]]:
        """The complete messages buffered so far (removed from the buffer)."""
        out = []
        while len(self.buffer) >= _HEADER.size:
            (size,) = _HEADER.unpack_from(self.buffer)
            if len(self.buffer) < _HEADER.size + size:
                break
            data = bytes(self.buffer[_HEADER.size:_HEADER.size + size])
            del self.buffer[:_HEADER.size + size]
            out.append(pickle.loads(data))
        return out


def _spawn(name: str, fn: Callable[[Callable[[Any], None]], Any], index: int, pools: Any
           ) -> _Child:
    """Fork a child running `fn` with its thread `pools` limited to one thread; the parent
    gets its pid and the pipe's read end. The pipe is made and the fork done under
    `_FDS_LOCK`, so that a child of a race running in another thread never holds this pipe:
    the child closes every race pipe of the process but its own write end (an inherited
    write end would keep the other race from seeing its arm's end)."""
    parent = os.getpid()
    with _FDS_LOCK:
        read, write = os.pipe()
        _OPEN_FDS.update((read, write))
        try:
            with warnings.catch_warnings():  # Python >= 3.12 warns about forking with threads
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
        except OSError:
            for fd in (read, write):
                _OPEN_FDS.discard(fd)
                os.close(fd)
            raise
        if pid == 0:  # the child: never returns
            for fd in _OPEN_FDS - {write}:
                with contextlib.suppress(OSError):
                    os.close(fd)
            _child(fn, write, parent, pools)
        _close(write)
    return _Child(name, index, pid, read, bytearray())


def _close(fd: int) -> None:
    """Close a race pipe's end in this process and forget it (under `_FDS_LOCK`, before its
    number can be reused by another pipe)."""
    with _FDS_LOCK:
        _OPEN_FDS.discard(fd)
        os.close(fd)


def _child(fn: Callable[[Callable[[Any], None]], Any], fd: int, parent: int, pools: Any
           ) -> None:
    """Run `fn` in the forked child and exit without running the parent's cleanup."""
    code = 0
    try:
        _die_with_parent(parent)
        with contextlib.suppress(ValueError):  # only the main thread may set handlers
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent ends the race
        stream = os.fdopen(fd, "wb")

        def send(kind: str, payload: Any) -> None:
            data = pickle.dumps((kind, payload), protocol=pickle.HIGHEST_PROTOCOL)
            stream.write(_HEADER.pack(len(data)) + data)
            stream.flush()

        try:
            with pools.limit(limits=1) if pools is not None else contextlib.nullcontext():
                value = fn(lambda message: send(_PROGRESS, message))
            send(_RESULT, value)
        except Exception as exc:  # reported to the parent as the arm's error
            send(_ERROR, f"{type(exc).__name__}: {exc}")
            code = 1
        stream.close()
    except BaseException:
        code = 1
    finally:
        os._exit(code)


def _die_with_parent(parent: int) -> None:
    """Ask Linux to kill this child when the thread that forked it ends (no-op elsewhere);
    exit at once if the parent already ended."""
    with contextlib.suppress(OSError, AttributeError):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:
        os._exit(1)


_POOLS: list[Any] = []


def _thread_pools() -> Any:
    """This process's BLAS/OpenMP thread pools (`threadpoolctl`, found once: the search
    takes ~10 ms), or None without threadpoolctl. A forked arm limits them to one thread, so
    that each arm gets one core."""
    if not _POOLS:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:  # pragma: no cover - a dependency; without it, pools as they are
            _POOLS.append(None)
        else:
            _POOLS.append(ThreadpoolController())
    return _POOLS[0]


def _reap(child: _Child, result: ArmResult, began: float) -> None:
    """Wait for an ended child; an arm that sent nothing says how it ended."""
    _, status = os.waitpid(child.pid, 0)
    _close(child.fd)
    if not child.done:
        result.seconds = time.perf_counter() - began
        result.error = (f"its process was killed by signal {os.WTERMSIG(status)}"
                        if os.WIFSIGNALED(status) else
                        f"its process exited with status {os.waitstatus_to_exitcode(status)} "
                        f"without a result")


def _end(children: Any, results: list[ArmResult], began: float, *, cancel: bool) -> None:
    """Kill every child still running and reap it (in a thread when it has not exited yet:
    the race need not wait for the kernel to free its memory); with `cancel`, mark their
    arms cancelled."""
    for child in list(children):
        with contextlib.suppress(ProcessLookupError):
            os.kill(child.pid, signal.SIGKILL)
        with contextlib.suppress(OSError):
            _close(child.fd)
        with contextlib.suppress(ChildProcessError):
            if os.waitpid(child.pid, os.WNOHANG) == (0, 0):
                threading.Thread(target=_wait, args=(child.pid,), daemon=True,
                                 name=f"reap-{child.pid}").start()
        result = results[child.index]
        if cancel and not child.done:
            result.cancelled = True
            result.seconds = time.perf_counter() - began


def _wait(pid: int) -> None:
    """Reap a killed child (no zombie is left behind)."""
    with contextlib.suppress(ChildProcessError):
        os.waitpid(pid, 0)


def _one_by_one(arms: Sequence[Arm], accept: Callable[[Any], bool],
                progress: Callable[[Any], None] | None) -> list[ArmResult]:
    """The arms in process, in order, until one is accepted (no `os.fork`)."""
    results = [ArmResult(name) for name, _ in arms]
    began = time.perf_counter()
    for result, (name, fn) in zip(results, arms, strict=True):
        def send(message: Any, name: str = name) -> None:
            if progress is not None:
                progress((name, message))
        try:
            result.value = fn(send)
        except Exception as exc:
            result.error = f"{type(exc).__name__}: {exc}"
        result.seconds = time.perf_counter() - began
        if result.error is None and accept(result.value):
            for rest in results[results.index(result) + 1:]:
                rest.cancelled = True
            break
    return results
