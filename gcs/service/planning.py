"""Planning jobs as Dask tasks: `planner.plan` on a Dask cluster, progress and results back on
the event loop.

The event loop never plans. By default the service runs an embedded `LocalCluster` (worker
processes, one thread each, `plan_workers` of them); with the `scheduler` setting it plans on
an existing cluster instead (`dask scheduler` + `dask worker`). Each plan is one task
(`plan_worker.run_plan`); its SCP iterations come back as Dask structured events on one topic
per service (`Client.subscribe_topic`), are appended to the job and fanned out to the SSE
stream. When the task returns, the plan text is stored (in a thread) and only then is the job
marked done, so a client told "done" always finds the plan in the database.

Bounded work:
- at most `plan_queue_max` jobs queued or running; beyond that `submit` raises `ServiceBusy`;
- small jobs first (Dask task priority by estimated work), and large jobs never take every
  worker: with N >= 2 workers at most N-1 large jobs run at once;
- a time limit per job (setting, or per request) enforced by the task itself after every SCP
  iteration and, if a single iteration overruns it, by restarting the worker;
- `cancel` sets the job's Dask Event (the task stops after its current iteration); a task
  still running `CANCEL_GRACE_S` later is stopped by restarting its worker (Nanny restart).

If the plan cannot be stored (disk full, database gone) the mission is marked `failed` with
that reason; if even that write fails, it is retried until it succeeds, so no mission stays
`planning` while the service runs (and the next start fails any left over).

Workers never outlive the service: the embedded cluster is closed on shutdown, and its
processes exit by themselves when the service dies (distributed's parent-alive pipe).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
import uuid
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from gcs.errors import InvalidRequest, ServiceBusy, StateConflict
from gcs.service import plan_worker
from gcs.service.events import Broadcast, Event
from gcs.service.store import Store
from gcs.tasks import TaskSet

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

    from gcs.service.settings import Settings

__all__ = ["CANCEL_GRACE_S", "LARGE_JOB_WORK", "PlanJob", "PlanningService", "job_work"]

log = logging.getLogger(__name__)

#: How long a cancelled or overrunning task may take to stop by itself before its worker is
#: restarted (an SCP iteration of a large plan can take several seconds).
CANCEL_GRACE_S = 5.0
#: Estimated work (vehicles^2 x steps: the pair rows the planner may check) above which a job
#: is "large": 16 vehicles over 250 steps.
LARGE_JOB_WORK = 16 * 16 * 250
#: A stopped job whose task had not started yet: how many times, how far apart (s), the
#: workers are asked whether it started after all.
STARTING_LOOKS = 4
STARTING_LOOK_S = 0.5
#: How long the workers may take to say which of a stopped job's tasks they still run (s).
WORKER_QUERY_S = 10.0
#: Retry period of a mission's final write when the store refused it.
STORE_RETRY_S = 2.0


def job_work(scenario: dict[str, Any]) -> int:
    """The job's estimated work: vehicles squared times steps."""
    vehicles = len(scenario.get("vehicles", ()))
    return vehicles * vehicles * int(scenario.get("steps", 0))


@dataclass
class PlanJob:
    """One mission being planned, as seen from the event loop."""

    mission_id: str
    key: str = ""
    """The Dask task key (unique per job)."""
    work: int = 0
    time_limit_s: float | None = None
    progress: list[dict[str, Any]] = field(default_factory=list)
    """Iteration records received so far (IterationRecord as dicts)."""
    outcome: dict[str, Any] | None = None
    """The final event: {"status": "planned"|"failed", "plan_status", "plan_ok", "error"}."""
    done: asyncio.Event = field(default_factory=asyncio.Event)
    started: asyncio.Event = field(default_factory=asyncio.Event)
    """Set when a worker began the task (the time limit counts from here)."""
    progress_complete: asyncio.Event = field(default_factory=asyncio.Event)
    """Set when the worker's end-of-progress marker arrived (all iterations delivered)."""
    ends_expected: int = 1
    """End-of-progress markers to wait for: one per task (a sequence: one per leg)."""
    ends_seen: int = 0
    worker: str | None = None
    running: dict[int | None, str] = field(default_factory=dict)
    """Workers running this job's tasks now, by leg (None: a single scenario's task)."""
    """Address of the worker running the task (from its `started` event)."""
    stop_reason: str | None = None
    """Why the job is being stopped (cancel, time limit), once it is."""
    future: Any = None
    """The Dask future while the task is submitted."""
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


def _failed(reason: str, field_name: str | None = None) -> dict[str, Any]:
    return {"status": "failed", "plan_status": None, "plan_ok": None,
            "error": {"field": field_name, "reason": reason}}


class PlanningService:
    """A Dask client (and, by default, its embedded cluster) and the jobs running on it."""

    def __init__(
        self,
        store: Store,
        *,
        workers: int,
        solver: str | None,
        scheduler: str | None = None,
        time_limit_s: float = 600.0,
        queue_max: int = 16,
        cancel_grace_s: float = CANCEL_GRACE_S,
    ) -> None:
        self._store = store
        self._workers = workers
        self._solver = solver
        self._scheduler = scheduler
        self._time_limit_s = time_limit_s
        self._queue_max = queue_max
        self._grace = cancel_grace_s
        self._cluster: LocalCluster | None = None
        self._client: Client | None = None
        self._topic = f"fleetplan-progress-{uuid.uuid4().hex[:12]}"
        self._jobs: dict[str, PlanJob] = {}
        self._by_key: dict[str, PlanJob] = {}
        self._tasks = TaskSet()
        self._large_slots: asyncio.Semaphore | None = None
        self._closing = False
        self.on_message: Callable[[dict[str, Any]], None] | None = None
        """Called with every worker message as it arrives (measurement hook)."""

    @classmethod
    def from_settings(cls, store: Store, settings: Settings) -> PlanningService:
        return cls(
            store,
            workers=settings.plan_workers,
            solver=settings.planner_solver,
            scheduler=settings.scheduler,
            time_limit_s=settings.plan_time_limit_s,
            queue_max=settings.plan_queue_max,
        )

    # ------------------------------------------------------------------ lifecycle

    @property
    def scheduler_address(self) -> str | None:
        """The Dask scheduler planning runs on (embedded or external), once started."""
        return None if self._client is None else self._client.scheduler.address

    @property
    def time_limit_s(self) -> float:
        """The longest a plan may compute (a request may ask for less)."""
        return self._time_limit_s

    async def start(self) -> None:
        """Connect to the scheduler (or start the embedded cluster); warm the workers."""
        import dask
        from distributed import Client, LocalCluster

        if self._scheduler:
            self._client = await Client(self._scheduler, asynchronous=True, timeout=10)
            workers = len(self._client.scheduler_info().get("workers", {})) or 1
        else:
            # A plan that kills its worker (out of memory) would kill the next one too.
            with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
                self._cluster = await LocalCluster(
                    n_workers=self._workers, threads_per_worker=1, processes=True,
                    host="127.0.0.1", scheduler_port=0, dashboard_address=None,
                    asynchronous=True, silence_logs=logging.WARNING,
                )
            self._client = await Client(self._cluster, asynchronous=True)
            workers = self._workers
        self._large_slots = asyncio.Semaphore(max(1, workers - 1))
        self._client.subscribe_topic(self._topic, self._on_event)
        # Import the planner on every worker now rather than on the first request.
        await self._client.run(plan_worker.warm)

    async def close(self) -> None:
        """Fail unfinished jobs, stop their tasks, close the client and embedded cluster."""
        self._closing = True
        unfinished = [job for job in self._jobs.values() if not job.done.is_set()]
        for job in unfinished:
            job.stop_reason = "the service stopped before this plan finished"
            await self._record_failure(job, job.stop_reason, retry=False)
            job.finish(_failed("the service stopped"))
        client = self._client
        if client is not None:  # tasks of an external cluster stop after their iteration
            for job in unfinished:
                if job.started.is_set():
                    with contextlib.suppress(Exception):
                        await self._cancel_flag(job).set()
        self._tasks.cancel_all()
        await self._tasks.wait(timeout=5)
        if client is not None:
            with contextlib.suppress(Exception):
                client.unsubscribe_topic(self._topic)
            with contextlib.suppress(Exception):
                await client.close(timeout=5)
            self._client = None
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                await self._cluster.close(timeout=10)
            self._cluster = None

    # ------------------------------------------------------------------ jobs

    def job(self, mission_id: str) -> PlanJob | None:
        """The in-memory job of a mission planned since this service started."""
        return self._jobs.get(mission_id)

    @property
    def active(self) -> int:
        """Jobs queued or running."""
        return sum(1 for job in self._jobs.values() if not job.done.is_set())

    def check_capacity(self) -> None:
        """ServiceBusy when the queue is full (call before storing a new mission)."""
        if self._closing:
            raise ServiceBusy("planning", "the service is stopping")
        if self.active >= self._queue_max:
            raise ServiceBusy("planning", f"{self.active} plans are queued or running, the "
                              f"limit (setting plan_queue_max); retry later")

    def job_time_limit(self, requested: float | None) -> float:
        """The time limit of a job: `requested` (at most the setting) or the setting."""
        if requested is None:
            return self._time_limit_s
        if not math.isfinite(requested) or requested <= 0:
            raise InvalidRequest("time_limit", "must be a positive number of seconds")
        if requested > self._time_limit_s:
            raise InvalidRequest("time_limit", f"must be at most {self._time_limit_s:g} s "
                                 "(setting plan_time_limit_s)")
        return requested

    def submit(
        self, mission_id: str, scenario: dict[str, Any], *, time_limit_s: float | None = None
    ) -> PlanJob:
        """Start planning a stored mission; the job finishes by itself."""
        assert self._client is not None, "service not started"
        self.check_capacity()
        job = PlanJob(mission_id, key=f"plan-{mission_id}-{uuid.uuid4().hex[:8]}",
                      work=job_work(scenario), time_limit_s=self.job_time_limit(time_limit_s))
        self._jobs[mission_id] = job
        self._by_key[job.key] = job
        self._tasks.spawn(self._run(job, scenario))
        return job

    def submit_sequence(
        self, mission_id: str, sequence: Any, *, time_limit_s: float | None = None
    ) -> PlanJob:
        """Start planning a stored mission that is a formation sequence (a parsed
        `planner.sequence.FormationSequence`): one Dask task per leg, all submitted at once
        (they run in parallel on the workers), then a task stitching and verifying the whole
        timeline. Progress records carry their `leg`; cancel and the time limit stop every
        leg through the job's one cancel flag."""
        assert self._client is not None, "service not started"
        self.check_capacity()
        steps = sum(sequence.holds) + sum(int(leg["steps"]) for leg in sequence.legs)
        work = len(sequence.ids) ** 2 * steps
        job = PlanJob(mission_id, key=f"plan-{mission_id}-{uuid.uuid4().hex[:8]}", work=work,
                      time_limit_s=self.job_time_limit(time_limit_s),
                      ends_expected=len(sequence.legs))
        self._jobs[mission_id] = job
        self._by_key[job.key] = job
        self._tasks.spawn(self._run(job, sequence))
        return job

    def cancel(self, mission_id: str, reason: str = "cancelled by the operator") -> PlanJob:
        """Stop a job: its task ends after its current iteration, or its worker is restarted
        `CANCEL_GRACE_S` later. Returns at once; await `job.done`."""
        job = self._jobs.get(mission_id)
        if job is None or job.done.is_set():
            raise StateConflict("mission_id", f"mission {mission_id!r} is not planning")
        self._stop(job, reason)
        return job

    def forget(self, mission_id: str) -> None:
        """Drop a finished job's in-memory state (after the mission is deleted)."""
        job = self._jobs.get(mission_id)
        if job is not None and job.done.is_set():
            del self._jobs[mission_id]
            self._by_key.pop(job.key, None)

    # ------------------------------------------------------------------ internals

    def _cancel_flag(self, job: PlanJob) -> Any:
        from distributed import Event as DaskEvent

        return DaskEvent(f"{job.key}-cancel", client=self._client)

    def _stop(self, job: PlanJob, reason: str) -> None:
        if job.stop_reason is not None:
            return
        job.stop_reason = reason
        self._tasks.spawn(self._enforce_stop(job))

    async def _enforce_stop(self, job: PlanJob) -> None:
        """Ask the task to stop; restart its worker if it has not stopped after the grace.

        Whether it stopped is asked of the workers themselves: a task cancelled just as it
        started (before its `started` event arrived) is forgotten by the scheduler and ends
        the job at once, but runs on in its worker until that worker is restarted."""
        stop_asked = time.monotonic()
        with contextlib.suppress(Exception):
            await self._cancel_flag(job).set()
        if not job.started.is_set() and job.future is not None:
            # Still queued on the scheduler: dropping the future removes the task.
            with contextlib.suppress(Exception):
                await job.future.cancel()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(job.done.wait(), self._grace)
        if self._client is None:
            return
        # A task dropped before its `started` event may still be on its way to a worker and
        # start a moment later: look again a few times before concluding it never ran.
        for look in range(1 if job.started.is_set() else STARTING_LOOKS):
            if look:
                await asyncio.sleep(STARTING_LOOK_S)
            stuck = await self._workers_running(job)
            if stuck:
                break
        left = stop_asked + self._grace - time.monotonic()
        if stuck and left > 0:  # the job ended early (dropped future): give the task its grace
            await asyncio.sleep(left)
            stuck = await self._workers_running(job)
        client = self._client
        if not stuck or client is None:
            return
        log.warning("plan %s did not stop within %.0f s (%s): restarting worker(s) %s",
                    job.mission_id, self._grace, job.stop_reason, stuck)
        future = job.future
        if future is not None:
            with contextlib.suppress(Exception):
                await future.cancel()
        try:
            await client.restart_workers(stuck, timeout=60, raise_for_error=False)
        except Exception:  # not restartable (no nanny): the task runs on, results dropped
            log.exception("could not restart worker(s) %s", stuck)

    async def _workers_running(self, job: PlanJob) -> list[str]:
        """Workers executing one of the job's tasks right now, by their own account (the
        job's `started` events as a fallback when they cannot be asked)."""
        client = self._client
        assert client is not None
        started = set(job.running.values())
        try:
            answers = await asyncio.wait_for(
                client.run(_executing_keys, job.key, on_error="return"), WORKER_QUERY_S)
        except Exception:  # the scheduler did not answer: go by the started events
            return sorted(started)
        running = {worker for worker, keys in answers.items()
                   if not isinstance(keys, BaseException) and keys}
        silent = {worker for worker, keys in answers.items() if isinstance(keys, BaseException)}
        return sorted(running | (started & silent))

    async def _watch_time(self, job: PlanJob) -> None:
        """Stop a job whose task has run past its limit (the task checks it itself too, but
        only between SCP iterations)."""
        await job.started.wait()
        assert job.time_limit_s is not None
        await asyncio.sleep(job.time_limit_s)
        if not job.done.is_set():
            self._stop(job, f"planning exceeded its time limit of {job.time_limit_s:g} s")

    async def _run(self, job: PlanJob, scenario: Any) -> None:
        watch = self._tasks.spawn(self._watch_time(job))
        try:
            if job.work > LARGE_JOB_WORK and self._large_slots is not None:
                async with self._large_slots:
                    result = await self._compute(job, scenario)
            else:
                result = await self._compute(job, scenario)
            await self._conclude(job, result)
        except asyncio.CancelledError:
            if not job.done.is_set():
                job.finish(_failed(job.stop_reason or "the service stopped"))
            raise
        finally:
            watch.cancel()
            job.future = None
            if job.stop_reason is not None:
                with contextlib.suppress(Exception):
                    await self._cancel_flag(job).clear()

    def _submit_tasks(self, job: PlanJob, scenario: Any) -> tuple[Any, list[Any]]:
        """The job's final future, and the futures it depends on (a sequence's legs)."""
        client = self._client
        assert client is not None
        options = {"topic": self._topic, "time_limit_s": job.time_limit_s,
                   "cancel_event": f"{job.key}-cancel"}
        if isinstance(scenario, dict):
            return client.submit(plan_worker.run_plan, job.key, scenario, self._solver,
                                 **options, key=job.key, pure=False, priority=-job.work,
                                 retries=0), []
        legs = [
            client.submit(plan_worker.run_plan, job.key, leg, self._solver, **options, leg=k,
                          key=f"{job.key}-leg{k}", pure=False, priority=-job.work, retries=0)
            for k, leg in enumerate(scenario.legs)
        ]
        stitched = client.submit(plan_worker.stitch_sequence, scenario, *legs, key=job.key,
                                 pure=False, priority=-job.work, retries=0)
        return stitched, legs

    async def _compute(self, job: PlanJob, scenario: Any) -> plan_worker.PlanOutcome:
        """Run the task(s); the outcome (with its `error` when it failed or was stopped)."""
        if job.stop_reason is not None:  # cancelled while waiting for a large-job slot
            return plan_worker.PlanOutcome.failed(job.stop_reason, stopped=True)
        future, legs = self._submit_tasks(job, scenario)
        job.future = future
        try:
            result = await future
        except Exception as exc:
            if job.stop_reason is not None:  # the worker was restarted to stop it
                return plan_worker.PlanOutcome.failed(job.stop_reason, stopped=True)
            name = type(exc).__name__
            if name == "KilledWorker":
                log.error("planner worker died while planning mission %s", job.mission_id)
                reason = ("the planner worker process died (out of memory?); try a smaller "
                          "scenario")
            else:  # a bug in the planner: report it, keep serving
                log.error("planning mission %s failed: %s: %s", job.mission_id, name, exc)
                reason = f"{name}: {exc}"
            return plan_worker.PlanOutcome.failed(reason)
        finally:
            for done in (future, *legs):
                with contextlib.suppress(Exception):
                    done.release()
        if job.stop_reason is not None and (result.error is None or result.stopped):
            # Stopped on request (or finished just as it was stopped: a cancel still wins):
            # the reason is the service's, not the task's generic one.
            return plan_worker.PlanOutcome.failed(job.stop_reason, stopped=True)
        # Let the last iterations (sent as events) arrive first.
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(job.progress_complete.wait(), 2.0)
        return result

    async def _conclude(self, job: PlanJob, result: plan_worker.PlanOutcome) -> None:
        """Store the result; a store that refuses the plan leaves the mission `failed`."""
        if job.done.is_set():  # already failed by close()
            return
        if result.error is not None:
            error = result.error
            await self._record_failure(job, error["reason"], error.get("field"))
            job.finish({"status": "failed", "plan_status": None, "plan_ok": None,
                        "error": error})
            return
        try:
            await asyncio.to_thread(
                self._store.finish_planning, job.mission_id, plan_json=result.plan_json,
                plan_status=result.status, plan_ok=result.ok,
            )
        except Exception as exc:
            log.error("could not store the plan of mission %s: %s", job.mission_id, exc)
            reason = f"the plan could not be stored: {_short(exc)}"
            await self._record_failure(job, reason)
            job.finish(_failed(reason))
            return
        job.finish({"status": "planned", "plan_status": result.status,
                    "plan_ok": result.ok, "error": None})

    async def _record_failure(
        self, job: PlanJob, reason: str, field_name: str | None = None, *, retry: bool = True
    ) -> None:
        """Mark the mission failed; while the store refuses, retry in the background."""
        error = {"field": field_name, "reason": reason}
        try:
            await asyncio.to_thread(self._store.fail_planning, job.mission_id, error)
        except Exception as exc:
            log.error("could not mark mission %s failed: %s", job.mission_id, exc)
            if retry and not self._closing:
                self._tasks.spawn(self._retry_failure(job.mission_id, error))

    async def _retry_failure(self, mission_id: str, error: dict[str, Any]) -> None:
        while not self._closing:
            await asyncio.sleep(STORE_RETRY_S)
            try:
                await asyncio.to_thread(self._store.fail_planning, mission_id, error)
                return
            except Exception:
                continue

    def _on_event(self, event: tuple[float, dict[str, Any]]) -> None:
        """A progress message from a worker (called on the event loop by the client)."""
        _, message = event
        job = self._by_key.get(str(message.get("job")))
        if job is None or job.done.is_set():
            return
        kind = message.get("kind")
        if self.on_message is not None:
            self.on_message(message)
        if kind == "iteration":
            job.add_progress(message["record"])
        elif kind == "started":
            job.worker = message.get("worker")
            if job.worker is not None:
                job.running[message.get("leg")] = job.worker
            job.started.set()
        elif kind == "end":
            job.running.pop(message.get("leg"), None)
            job.ends_seen += 1
            if job.ends_seen >= job.ends_expected:
                job.progress_complete.set()


def _executing_keys(prefix: str, dask_worker: Any = None) -> list[str]:
    """Keys of the tasks starting with `prefix` that this worker executes (run on workers)."""
    return [str(task.key) for task in dask_worker.state.executing
            if str(task.key).startswith(prefix)]


def _short(exc: BaseException) -> str:
    """An exception in one line (SQLAlchemy's messages carry the statement and a URL)."""
    text = str(getattr(exc, "orig", None) or exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}"[:300]
