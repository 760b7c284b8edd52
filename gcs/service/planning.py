"""Planning jobs as Dask tasks: `planner.plan` on a Dask cluster, progress and results back on
the event loop.

The event loop never plans. `PlanningService` is the one face of planning the API uses; it
joins three parts, each with one job:
- `gcs.service.plan_jobs`: the job itself and the bounded queue (`plan_queue_max` jobs queued,
  running or reserved; beyond that ServiceBusy). `reserve()` takes a place before a mission is
  stored, so a refused request stores nothing;
- `gcs.service.plan_engine`: the Dask client and (by default) its embedded cluster;
- `gcs.service.plan_runner`: running a job, its time limit, cancel, and the stored outcome.

Workers never outlive the service: the embedded cluster is closed on shutdown, and its
processes exit by themselves when the service dies.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from gcs.errors import StateConflict
from gcs.service.plan_engine import DaskEngine
from gcs.service.plan_jobs import (
    LARGE_JOB_WORK,
    Admission,
    PlanJob,
    Reservation,
    job_work,
    sequence_work,
)
from gcs.service.plan_runner import CANCEL_GRACE_S, JobRunner
from gcs.service.store import Store
from gcs.tasks import TaskSet

if TYPE_CHECKING:
    from gcs.service.settings import Settings

__all__ = [
    "CANCEL_GRACE_S",
    "LARGE_JOB_WORK",
    "PlanJob",
    "PlanningService",
    "Reservation",
    "job_work",
]


class PlanningService:
    """The planning queue, the Dask engine it runs on and the jobs running there."""

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
        self._tasks = TaskSet()
        self._queue = Admission(queue_max=queue_max, time_limit_s=time_limit_s)
        self._engine = DaskEngine(workers=workers, solver=solver, scheduler=scheduler)
        self._runner = JobRunner(store, self._engine, self._tasks, grace_s=cancel_grace_s)
        self.on_message: Callable[[dict[str, Any]], None] | None = None
        """Called with every worker message as it arrives (measurement hook)."""

    @classmethod
    def from_settings(cls, store: Store, settings: Settings) -> PlanningService:
        """The service the settings describe (workers, solver, scheduler, limits)."""
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
        return self._engine.scheduler_address

    @property
    def time_limit_s(self) -> float:
        """The longest a plan may compute (a request may ask for less)."""
        return self._queue.time_limit_s

    @property
    def queue_max(self) -> int:
        """Most plans queued, running or reserved at once (setting plan_queue_max)."""
        return self._queue.queue_max

    async def start(self) -> None:
        """Connect to the scheduler (or start the embedded cluster); warm the workers."""
        await self._engine.start(self._on_message)
        self._runner.open_large_slots(self._engine.workers)

    async def close(self) -> None:
        """Fail unfinished jobs, stop their tasks, close the client and embedded cluster."""
        self._queue.closing = self._runner.closing = True
        unfinished = [job for job in self._queue.jobs.values() if not job.done.is_set()]
        for job in unfinished:
            await self._runner.fail_unfinished(
                job, "the service stopped before this plan finished")
        if self._engine.started:  # tasks of an external cluster stop after their iteration
            for job in unfinished:
                if job.started.is_set():
                    with contextlib.suppress(Exception):
                        await self._engine.cancel_flag(job).set()
        self._tasks.cancel_all()
        await self._tasks.wait(timeout=5)
        await self._engine.close()

    # ------------------------------------------------------------------ jobs

    def job(self, mission_id: str) -> PlanJob | None:
        """The in-memory job of a mission planned since this service started."""
        return self._queue.jobs.get(mission_id)

    @property
    def active(self) -> int:
        """Jobs queued or running."""
        return self._queue.active

    def check_capacity(self) -> None:
        """ServiceBusy when the queue is full or the service is stopping."""
        self._queue.check_capacity()

    def reserve(self) -> Reservation:
        """A place in the queue and the id for a mission about to be stored (ServiceBusy
        when full). Pass it to `submit`; `release()` it if the mission is not submitted."""
        return self._queue.reserve()

    def holds(self, mission_id: str) -> bool:
        """A running job, or a reservation, holds this mission (it is really planning)."""
        return self._queue.holds(mission_id)

    def job_time_limit(self, requested: float | None) -> float:
        """The time limit of a job: `requested` (at most the setting) or the setting."""
        return self._queue.time_limit(requested)

    def submit(
        self, mission_id: str, scenario: dict[str, Any], *, time_limit_s: float | None = None,
        reservation: Reservation | None = None,
    ) -> PlanJob:
        """Start planning a stored mission (in its reservation's place, if any); the job
        finishes by itself."""
        job = PlanJob.new(mission_id, work=job_work(scenario),
                          time_limit_s=self.job_time_limit(time_limit_s))
        return self._start(job, scenario, reservation)

    def submit_sequence(
        self, mission_id: str, sequence: Any, *, time_limit_s: float | None = None,
        reservation: Reservation | None = None,
    ) -> PlanJob:
        """Start planning a stored mission that is a formation sequence (a parsed
        `planner.methods.sequence.FormationSequence`): one Dask task per leg, all submitted at once
        (they run in parallel on the workers), then a task stitching and verifying the whole
        timeline. Progress records carry their `leg`; cancel and the time limit stop every
        leg through the job's one cancel flag."""
        job = PlanJob.new(mission_id, work=sequence_work(sequence),
                          time_limit_s=self.job_time_limit(time_limit_s),
                          ends_expected=len(sequence.jobs))
        return self._start(job, sequence, reservation)

    def _start(self, job: PlanJob, scenario: Any, reservation: Reservation | None) -> PlanJob:
        if not self._engine.started:
            raise RuntimeError("the planning service is not started")
        self._queue.admit(job, reservation)
        self._runner.start(job, scenario)
        return job

    def cancel(self, mission_id: str, reason: str = "cancelled by the operator") -> PlanJob:
        """Stop a job: its task ends after its current iteration, or its worker is restarted
        `CANCEL_GRACE_S` later. Returns at once; await `job.done`."""
        job = self._queue.jobs.get(mission_id)
        if job is None or job.done.is_set():
            raise StateConflict("mission_id", f"mission {mission_id!r} is not planning")
        self._runner.stop(job, reason)
        return job

    def forget(self, mission_id: str) -> None:
        """Drop a finished job's in-memory state (after the mission is deleted)."""
        self._queue.forget(mission_id)

    def _on_message(self, message: dict[str, Any]) -> None:
        """A progress message from a worker (called on the event loop by the client)."""
        job = self._queue.by_key.get(str(message.get("job")))
        if job is None or job.done.is_set():
            return
        if self.on_message is not None:
            self.on_message(message)
        job.on_message(message)
