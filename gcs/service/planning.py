"""Planning jobs: `planner.plan` in worker processes, progress and results back on the loop.

The event loop never plans. `PlanningService.submit` hands the scenario to a
`ProcessPoolExecutor` (spawn start method: no forked locks, no inherited sockets); every SCP
iteration comes back through one `multiprocessing` queue drained by a reader thread, which
passes it to the loop with `call_soon_threadsafe`. When the worker returns, the plan text is
stored (in a thread) and only then is the job marked done, so a client told "done" always
finds the plan in the database.

Subscribers (the SSE progress stream) get every iteration and one final event; a subscriber
arriving late first gets the iterations so far.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import threading
from collections.abc import AsyncIterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from gcs.service import plan_worker
from gcs.service.events import Broadcast, Event
from gcs.service.store import Store

__all__ = ["PlanJob", "PlanningService"]

log = logging.getLogger(__name__)


@dataclass
class PlanJob:
    """One mission being planned, as seen from the event loop."""

    mission_id: str
    progress: list[dict[str, Any]] = field(default_factory=list)
    """Iteration records received so far (IterationRecord as dicts)."""
    outcome: dict[str, Any] | None = None
    """The final event: {"status": "planned"|"failed", "plan_status", "plan_ok", "error"}."""
    done: asyncio.Event = field(default_factory=asyncio.Event)
    progress_complete: asyncio.Event = field(default_factory=asyncio.Event)
    """Set when the worker's end-of-progress marker arrived (all iterations delivered)."""
    listeners: Broadcast = field(default_factory=Broadcast)

    def add_progress(self, record: dict[str, Any]) -> None:
        self.progress.append(record)
        self.listeners.publish("iteration", record)

    def finish(self, outcome: dict[str, Any]) -> None:
        self.outcome = outcome
        self.done.set()
        self.listeners.publish("done", outcome)

    async def events(self) -> AsyncIterator[Event]:
        """("iteration", record)... then ("done", outcome): history first, then live."""
        history = [("iteration", record) for record in self.progress]
        done = None if self.outcome is None else ("done", self.outcome)
        async for event in self.listeners.follow(history, done):
            yield event


class PlanningService:
    """A pool of planner processes and the jobs running on it."""

    def __init__(self, store: Store, *, workers: int, solver: str | None) -> None:
        self._store = store
        self._workers = workers
        self._solver = solver
        self._context = multiprocessing.get_context("spawn")
        self._queue: Any = None
        self._pool: ProcessPoolExecutor | None = None
        self._reader: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._jobs: dict[str, PlanJob] = {}
        self._tasks: set[asyncio.Task[None]] = set()

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._queue = self._context.Queue()
        self._reader = threading.Thread(
            target=self._read_progress, name="plan-progress", daemon=True
        )
        self._reader.start()
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        pool = ProcessPoolExecutor(
            max_workers=self._workers,
            mp_context=self._context,
            initializer=plan_worker.init_worker,
            initargs=(self._queue,),
        )
        # Start the workers now (they import the planner) rather than on the first request.
        pool.submit(int)
        return pool

    async def close(self) -> None:
        """Stop the workers (a running plan is abandoned) and the reader thread."""
        for job in list(self._jobs.values()):
            if not job.done.is_set():
                await asyncio.to_thread(
                    self._store.fail_planning,
                    job.mission_id,
                    {"field": None, "reason": "the service stopped before this plan finished"},
                )
                job.finish(
                    {"status": "failed", "plan_status": None, "plan_ok": None,
                     "error": {"field": None, "reason": "the service stopped"}}
                )
        if self._pool is not None:
            self._terminate(self._pool)
            self._pool = None
        if self._queue is not None:
            self._queue.put(None)
            if self._reader is not None:
                await asyncio.to_thread(self._reader.join, 5)
            self._queue.close()
            self._queue = None
        for task in list(self._tasks):
            task.cancel()

    @staticmethod
    def _terminate(pool: ProcessPoolExecutor) -> None:
        # The executor has no public way to stop a running task (3.14 adds
        # terminate_workers); a plan can take minutes, so its processes are ended directly.
        processes = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            with contextlib.suppress(Exception):
                process.terminate()
        for process in processes:
            with contextlib.suppress(Exception):
                process.join(5)

    # ------------------------------------------------------------------ jobs

    def job(self, mission_id: str) -> PlanJob | None:
        """The in-memory job of a mission planned since this service started."""
        return self._jobs.get(mission_id)

    @property
    def active(self) -> int:
        return sum(1 for job in self._jobs.values() if not job.done.is_set())

    def submit(self, mission_id: str, scenario: dict[str, Any]) -> PlanJob:
        """Start planning a stored mission; the job finishes by itself."""
        assert self._pool is not None and self._loop is not None, "service not started"
        job = PlanJob(mission_id)
        self._jobs[mission_id] = job
        pool = self._pool
        future = pool.submit(plan_worker.run_plan, mission_id, scenario, self._solver)
        loop = self._loop
        future.add_done_callback(
            lambda f: loop.call_soon_threadsafe(self._on_done, job, f, pool)
        )
        return job

    def forget(self, mission_id: str) -> None:
        """Drop a finished job's in-memory state (after the mission is deleted)."""
        job = self._jobs.get(mission_id)
        if job is not None and job.done.is_set():
            del self._jobs[mission_id]

    def _on_done(
        self, job: PlanJob, future: Future[dict[str, Any]], pool: ProcessPoolExecutor
    ) -> None:
        task = asyncio.ensure_future(self._finish(job, future, pool))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _finish(
        self, job: PlanJob, future: Future[dict[str, Any]], pool: ProcessPoolExecutor
    ) -> None:
        if job.done.is_set():  # already failed by close()
            return
        try:
            result = future.result()
        except BrokenProcessPool:
            log.error("planner worker died while planning mission %s", job.mission_id)
            result = {"error": {"field": None, "reason": "the planner worker process died "
                                "(out of memory?); try a smaller scenario"}}
            if pool is self._pool:  # every job of a broken pool fails; replace it once
                self._replace_broken_pool()
        except Exception as exc:  # a bug in the planner: report it, keep serving
            log.exception("planning mission %s failed", job.mission_id)
            result = {"error": {"field": None, "reason": f"{type(exc).__name__}: {exc}"}}
        else:
            # Let the last iterations (sent on the progress queue) arrive first.
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(job.progress_complete.wait(), 2.0)
        if "error" in result:
            await asyncio.to_thread(self._store.fail_planning, job.mission_id, result["error"])
            outcome = {"status": "failed", "plan_status": None, "plan_ok": None,
                       "error": result["error"]}
        else:
            await asyncio.to_thread(
                self._store.finish_planning,
                job.mission_id,
                plan_json=result["plan_json"],
                plan_status=result["status"],
                plan_ok=result["ok"],
            )
            outcome = {"status": "planned", "plan_status": result["status"],
                       "plan_ok": result["ok"], "error": None}
        job.finish(outcome)

    def _replace_broken_pool(self) -> None:
        if self._pool is None:
            return
        broken, self._pool = self._pool, None
        self._terminate(broken)
        self._pool = self._new_pool()

    def _read_progress(self) -> None:
        """Reader thread: progress messages from the workers to the loop."""
        queue, loop = self._queue, self._loop
        assert queue is not None and loop is not None
        while True:
            try:
                message = queue.get()
            except (EOFError, OSError):
                return
            if message is None:
                return
            job_id, record = message  # record None: that job's progress is complete
            with contextlib.suppress(RuntimeError):  # loop closed during shutdown
                loop.call_soon_threadsafe(self._deliver, job_id, record)

    def _deliver(self, job_id: str, record: dict[str, Any] | None) -> None:
        job = self._jobs.get(job_id)
        if job is None or job.done.is_set():
            return
        if record is None:
            job.progress_complete.set()
        else:
            job.add_progress(record)
