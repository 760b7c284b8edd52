"""Running and watching plan jobs: from submission to the stored result, with the time limit,
cancellation and the large-job slots enforced on the way.

- Large jobs never take every worker: with N >= 2 workers at most N-1 run at once.
- The time limit counts from the task's start; the task checks it itself after every SCP
  iteration, and the runner stops a task whose single iteration overruns it.
- A stop sets the job's cancel flag (the task ends after its current iteration); a task still
  running `grace_s` later is stopped by restarting its worker (Nanny restart). Another job's
  task queued on that worker dies with it; it is submitted again (`RESTART_RESUBMITS`), so a
  plan posted just after a cancel does not fail for it.
- The plan text is stored (in a thread) before the job is marked done, so a client told
  "done" always finds the plan in the database. A plan the store refuses leaves the mission
  `failed` with that reason; if even that write fails, it is retried until it succeeds, so no
  mission stays `planning` while the service runs.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import Any

from gcs.service import plan_worker
from gcs.service.plan_engine import DaskEngine
from gcs.service.plan_jobs import LARGE_JOB_WORK, PlanJob, failed_outcome
from gcs.service.store import Store
from gcs.tasks import TaskSet

__all__ = ["CANCEL_GRACE_S", "RESTART_RESUBMITS", "STARTING_LOOKS", "STARTING_LOOK_S",
           "STORE_RETRY_S", "JobRunner"]

log = logging.getLogger(__name__)

#: How long a cancelled or overrunning task may take to stop by itself before its worker is
#: restarted (an SCP iteration of a large plan can take several seconds).
CANCEL_GRACE_S = 5.0
#: A stopped job whose task had not started yet: how many times, how far apart (s), the
#: workers are asked whether it started after all.
STARTING_LOOKS = 4
STARTING_LOOK_S = 0.5
#: How many times a task killed with a worker the service restarted (to stop another job's
#: task) is submitted again before its death is reported as the plan's.
RESTART_RESUBMITS = 2
#: Retry period of a mission's final write when the store refused it.
STORE_RETRY_S = 2.0
#: How long the last iterations (sent as events) may trail the task's result (s).
PROGRESS_TRAIL_S = 2.0


class JobRunner:
    """Runs admitted jobs on the engine and stores their outcome."""

    def __init__(self, store: Store, engine: DaskEngine, tasks: TaskSet, *,
                 grace_s: float = CANCEL_GRACE_S) -> None:
        self._store = store
        self._engine = engine
        self._tasks = tasks
        self.grace_s = grace_s
        self.closing = False
        self._large_slots: asyncio.Semaphore | None = None

    def open_large_slots(self, workers: int) -> None:
        """Allow at most `workers - 1` (at least one) large jobs at once."""
        self._large_slots = asyncio.Semaphore(max(1, workers - 1))

    def start(self, job: PlanJob, scenario: Any) -> None:
        """Run the job in the background; it finishes by itself."""
        self._tasks.spawn(self._run(job, scenario))

    def stop(self, job: PlanJob, reason: str) -> None:
        """Stop the job (once): its task ends after its current iteration, or its worker is
        restarted after the grace."""
        if job.stop_reason is not None:
            return
        job.stop_reason = reason
        self._tasks.spawn(self._enforce_stop(job))

    async def fail_unfinished(self, job: PlanJob, reason: str) -> None:
        """Fail a job the service gives up on (it is stopping) without retrying the write."""
        job.stop_reason = reason
        await self.record_failure(job.mission_id, reason, retry=False)
        job.finish(failed_outcome("the service stopped"))

    async def _enforce_stop(self, job: PlanJob) -> None:
        """Ask the task to stop; restart its worker if it has not stopped after the grace.
        The cancel flag is cleared only then: a task dropped just as it started, which a
        busy worker may begin seconds later, still finds it set and stops by itself."""
        try:
            await self._stop_or_restart(job)
        finally:
            if self._engine.started:
                with contextlib.suppress(Exception):
                    await self._engine.cancel_flag(job).clear()

    async def _stop_or_restart(self, job: PlanJob) -> None:
        """Whether the task stopped is asked of the workers themselves: a task cancelled just
        as it started (before its `started` event arrived) is forgotten by the scheduler and
        ends the job at once, but runs on in its worker until that worker is restarted."""
        stop_asked = time.monotonic()
        with contextlib.suppress(Exception):
            await self._engine.cancel_flag(job).set()
        if not job.started.is_set() and job.future is not None:
            # Still queued on the scheduler: dropping the future removes the task.
            with contextlib.suppress(Exception):
                await job.future.cancel()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(job.done.wait(), self.grace_s)
        if not self._engine.started:
            return
        # A task dropped before its `started` event may still be on its way to a worker and
        # start a moment later: look again a few times before concluding it never ran.
        stuck: list[str] = []
        for look in range(1 if job.started.is_set() else STARTING_LOOKS):
            if look:
                await asyncio.sleep(STARTING_LOOK_S)
            stuck = await self._engine.workers_running(job)
            if stuck:
                break
        left = stop_asked + self.grace_s - time.monotonic()
        if stuck and left > 0:  # the job ended early (dropped future): give the task its grace
            await asyncio.sleep(left)
            stuck = await self._engine.workers_running(job)
        if not stuck or not self._engine.started:
            return
        log.warning("plan %s did not stop within %.0f s (%s): restarting worker(s) %s",
                    job.mission_id, self.grace_s, job.stop_reason, stuck)
        future = job.future
        if future is not None:
            with contextlib.suppress(Exception):
                await future.cancel()
        await self._engine.restart_workers(stuck)

    async def _watch_time(self, job: PlanJob) -> None:
        """Stop a job whose task has run past its limit (the task checks it itself too, but
        only between SCP iterations)."""
        await job.started.wait()
        assert job.time_limit_s is not None
        await asyncio.sleep(job.time_limit_s)
        if not job.done.is_set():
            self.stop(job, f"planning exceeded its time limit of {job.time_limit_s:g} s")

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
                job.finish(failed_outcome(job.stop_reason or "the service stopped"))
            raise
        finally:
            watch.cancel()
            job.future = None

    async def _compute(self, job: PlanJob, scenario: Any) -> plan_worker.PlanOutcome:
        """Run the task(s); the outcome (with its `error` when it failed or was stopped)."""
        for attempt in range(RESTART_RESUBMITS + 1):
            if job.stop_reason is not None:  # cancelled while waiting for a slot or a retry
                return plan_worker.PlanOutcome.failed(job.stop_reason, stopped=True)
            mark = self._engine.restart_mark()
            future, legs = self._engine.submit(job, scenario, attempt)
            job.future = future
            try:
                result: plan_worker.PlanOutcome = await future
                break
            except Exception as exc:
                if job.stop_reason is not None:  # the worker was restarted to stop it
                    return plan_worker.PlanOutcome.failed(job.stop_reason, stopped=True)
                name = type(exc).__name__
                if (name == "KilledWorker" and self._engine.restarted_since(mark)
                        and attempt < RESTART_RESUBMITS):
                    # Queued on a worker the service restarted to stop another job's task:
                    # not this plan's doing, so it goes to the workers again.
                    log.warning("mission %s: its task went with a restarted worker; "
                                "submitted again", job.mission_id)
                    continue
                return _failed_task(job, name, exc)
            finally:
                for done in (future, *legs):
                    with contextlib.suppress(Exception):
                        done.release()
        if job.stop_reason is not None and (result.error is None or result.stopped):
            # Stopped on request (or finished just as it was stopped: a cancel still wins):
            # the reason is the service's, not the task's generic one.
            return plan_worker.PlanOutcome.failed(job.stop_reason, stopped=True)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(job.progress_complete.wait(), PROGRESS_TRAIL_S)
        return result

    async def _conclude(self, job: PlanJob, result: plan_worker.PlanOutcome) -> None:
        """Store the result; a store that refuses the plan leaves the mission `failed`."""
        if job.done.is_set():  # already failed by the service's close
            return
        if result.error is not None or result.plan_json is None or result.status is None:
            error = result.error or {"field": None, "reason": "the planner returned no plan"}
            await self.record_failure(job.mission_id, error["reason"], error.get("field"))
            job.finish({"status": "failed", "plan_status": None, "plan_ok": None,
                        "error": error})
            return
        try:
            await asyncio.to_thread(
                self._store.finish_planning, job.mission_id, plan_json=result.plan_json,
                plan_status=result.status, plan_ok=result.ok, steps=result.steps,
            )
        except Exception as exc:
            log.error("could not store the plan of mission %s: %s", job.mission_id, exc)
            reason = f"the plan could not be stored: {_short(exc)}"
            await self.record_failure(job.mission_id, reason)
            job.finish(failed_outcome(reason))
            return
        job.finish({"status": "planned", "plan_status": result.status,
                    "plan_ok": result.ok, "error": None})

    async def record_failure(
        self, mission_id: str, reason: str, field_name: str | None = None, *,
        retry: bool = True,
    ) -> None:
        """Mark the mission failed; while the store refuses, retry in the background."""
        error = {"field": field_name, "reason": reason}
        try:
            await asyncio.to_thread(self._store.fail_planning, mission_id, error)
        except Exception as exc:
            log.error("could not mark mission %s failed: %s", mission_id, exc)
            if retry and not self.closing:
                self._tasks.spawn(self._retry_failure(mission_id, error))

    async def _retry_failure(self, mission_id: str, error: dict[str, Any]) -> None:
        while not self.closing:
            await asyncio.sleep(STORE_RETRY_S)
            try:
                await asyncio.to_thread(self._store.fail_planning, mission_id, error)
                return
            except Exception:
                continue


def _failed_task(job: PlanJob, name: str, exc: Exception) -> plan_worker.PlanOutcome:
    """The outcome of a task that raised `exc` (named `name`): its worker died, or a bug."""
    if name == "KilledWorker":
        log.error("planner worker died while planning mission %s", job.mission_id)
        reason = "the planner worker process died (out of memory?); try a smaller scenario"
    else:  # a bug in the planner: report it, keep serving
        log.error("planning mission %s failed: %s: %s", job.mission_id, name, exc)
        reason = f"{name}: {exc}"
    return plan_worker.PlanOutcome.failed(reason)


def _short(exc: BaseException) -> str:
    """An exception in one line (SQLAlchemy's messages carry the statement and a URL)."""
    text = str(getattr(exc, "orig", None) or exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}"[:300]
