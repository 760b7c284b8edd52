"""Plan jobs and their admission: what one mission being planned holds, and the bounded queue
that decides whether another may start.

A job is admitted in two steps so a refusal never leaves anything behind: `Admission.reserve`
takes a place in the queue (ServiceBusy when it is full) and names the mission-to-be, the
caller stores the mission under that id, and `Admission.admit` turns the reservation into
the running job; a reservation not admitted is released, so its place is free again. A
reserved place counts against `plan_queue_max` exactly like a running job.
"""

from __future__ import annotations

import asyncio
import math
import time
import uuid
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

from gcs.errors import InvalidRequest, ServiceBusy
from gcs.service.events import Broadcast, Event
from gcs.service.plan_progress import planning_summary
from gcs.service.store import new_mission_id

__all__ = [
    "LARGE_JOB_WORK",
    "Admission",
    "PlanJob",
    "Reservation",
    "failed_outcome",
    "job_work",
    "sequence_work",
]

#: Estimated work (vehicles^2 x steps: the pair rows the planner may check) above which a job
#: is "large": 16 vehicles over 250 steps.
LARGE_JOB_WORK = 16 * 16 * 250


def job_work(scenario: dict[str, Any]) -> int:
    """The job's estimated work: vehicles squared times steps (for `steps: "auto"`, the
    most the search may try: `max_horizon` / dt)."""
    vehicles = len(scenario.get("vehicles", ()))
    steps = scenario.get("steps", 0)
    if not isinstance(steps, int):
        steps = round(float(scenario.get("max_horizon", 0.0)) / float(scenario["dt"]))
    return vehicles * vehicles * steps


def sequence_work(sequence: Any) -> int:
    """A formation sequence's estimated work: vehicles squared times its whole timeline."""
    from planner.methods.sequence import timeline_steps

    return len(sequence.ids) ** 2 * timeline_steps(sequence)


def failed_outcome(reason: str, field_name: str | None = None) -> dict[str, Any]:
    """A job's final event when it produced no plan."""
    return {"status": "failed", "plan_status": None, "plan_ok": None,
            "error": {"field": field_name, "reason": reason}}


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
    working: dict[str, Any] | None = None
    """The last report from inside the iteration under way (IterationProgress as a dict),
    until that iteration's record arrives."""
    started_at: float | None = None
    """When a worker first began one of the job's tasks (time.monotonic)."""
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
    """Address of the worker that last reported starting one of the job's tasks."""
    running: dict[int | None, str] = field(default_factory=dict)
    """Workers running this job's tasks now, by leg (None: a single scenario's task)."""
    stop_reason: str | None = None
    """Why the job is being stopped (cancel, time limit), once it is."""
    future: Any = None
    """The Dask future while the task is submitted."""
    listeners: Broadcast = field(default_factory=Broadcast)

    @classmethod
    def new(cls, mission_id: str, *, work: int, time_limit_s: float, ends_expected: int = 1
            ) -> PlanJob:
        """A job with a fresh, unique Dask task key."""
        return cls(mission_id, key=f"plan-{mission_id}-{uuid.uuid4().hex[:8]}", work=work,
                   time_limit_s=time_limit_s, ends_expected=ends_expected)

    def add_progress(self, record: dict[str, Any]) -> None:
        """Append one SCP iteration record and tell the listeners."""
        self.progress.append(record)
        self.working = None
        self.listeners.publish("iteration", record)

    def summary(self) -> dict[str, Any]:
        """The progress as `GET /api/missions/{id}` and the `working` events give it
        (`gcs.service.plan_progress`)."""
        elapsed = None if self.started_at is None else time.monotonic() - self.started_at
        return planning_summary(self.progress, self.working, elapsed)

    def finish(self, outcome: dict[str, Any]) -> None:
        """Set the final event (once the mission's row says the same)."""
        self.outcome = outcome
        self.done.set()
        self.listeners.publish("done", outcome)

    def on_message(self, message: dict[str, Any]) -> None:
        """A progress message from one of the job's tasks: iteration, started or end."""
        kind = message.get("kind")
        if kind == "iteration":
            self.add_progress(message["record"])
        elif kind == "working":
            self.working = message["record"]
            self.listeners.publish("working", self.summary())
        elif kind == "started":
            if self.started_at is None:
                self.started_at = time.monotonic()
            self.worker = message.get("worker")
            if self.worker is not None:
                self.running[message.get("leg")] = self.worker
            self.started.set()
        elif kind == "end":
            self.running.pop(message.get("leg"), None)
            self.ends_seen += 1
            if self.ends_seen >= self.ends_expected:
                self.progress_complete.set()

    async def events(self) -> AsyncIterator[Event]:
        """("iteration", record)... then ("done", outcome): history first, then live."""
        history = [("iteration", record) for record in self.progress]
        done = None if self.outcome is None else ("done", self.outcome)
        async for event in self.listeners.follow(history, done):
            yield event


@dataclass
class Reservation:
    """A place in the planning queue, held for one mission about to be stored."""

    mission_id: str
    """The id to store the mission under."""
    admission: Admission
    used: bool = False
    """Admitted as a job (or released): the place is no longer the reservation's."""

    def release(self) -> None:
        """Give the place back unless it became a job (safe to call more than once)."""
        if not self.used:
            self.used = True
            self.admission.reserved.pop(self.mission_id, None)


class Admission:
    """The bounded queue: the jobs of this service, by mission, and places reserved for
    missions being stored. At most `queue_max` jobs are queued or running or reserved."""

    def __init__(self, *, queue_max: int, time_limit_s: float) -> None:
        self.queue_max = queue_max
        self.time_limit_s = time_limit_s
        self.closing = False
        self.jobs: dict[str, PlanJob] = {}
        self.by_key: dict[str, PlanJob] = {}
        self.reserved: dict[str, Reservation] = {}

    @property
    def active(self) -> int:
        """Jobs queued or running (reservations not included)."""
        return sum(1 for job in self.jobs.values() if not job.done.is_set())

    def check_capacity(self) -> None:
        """ServiceBusy when the queue (jobs and reservations) is full or the service stops."""
        if self.closing:
            raise ServiceBusy("planning", "the service is stopping")
        held = self.active + len(self.reserved)
        if held >= self.queue_max:
            raise ServiceBusy("planning", f"{held} plans are queued or running, the limit "
                              f"(setting plan_queue_max); retry later")

    def reserve(self) -> Reservation:
        """A place in the queue for a mission not stored yet (ServiceBusy when full)."""
        self.check_capacity()
        reservation = Reservation(new_mission_id(), self)
        self.reserved[reservation.mission_id] = reservation
        return reservation

    def holds(self, mission_id: str) -> bool:
        """A job still running, or a reservation, holds this mission."""
        job = self.jobs.get(mission_id)
        return mission_id in self.reserved or (job is not None and not job.done.is_set())

    def time_limit(self, requested: float | None) -> float:
        """The time limit of a job: `requested` (at most the setting) or the setting."""
        if requested is None:
            return self.time_limit_s
        if not math.isfinite(requested) or requested <= 0:
            raise InvalidRequest("time_limit", "must be a positive number of seconds")
        if requested > self.time_limit_s:
            raise InvalidRequest("time_limit", f"must be at most {self.time_limit_s:g} s "
                                 "(setting plan_time_limit_s)")
        return requested

    def admit(self, job: PlanJob, reservation: Reservation | None) -> None:
        """Register a job: in its reservation's place, or in a free one (ServiceBusy)."""
        if reservation is None or reservation.used:
            self.check_capacity()
        else:
            if reservation.mission_id != job.mission_id:
                raise ValueError("the reservation is for another mission")
            if self.closing:
                raise ServiceBusy("planning", "the service is stopping")
            reservation.release()
        self.jobs[job.mission_id] = job
        self.by_key[job.key] = job

    def forget(self, mission_id: str) -> None:
        """Drop a finished job's in-memory state."""
        job = self.jobs.get(mission_id)
        if job is not None and job.done.is_set():
            del self.jobs[mission_id]
            self.by_key.pop(job.key, None)
