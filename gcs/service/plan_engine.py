"""The Dask engine planning runs on: the client, the embedded cluster (by default), the task
submission, the progress topic, and the worker-side questions and restarts that stop a task.

By default the engine runs an embedded `LocalCluster` (worker processes, one thread each);
with a scheduler address it plans on an existing cluster instead (`dask scheduler` +
`dask worker`). Each plan is one task (`plan_worker.run_plan`; a sequence: one per leg and a
stitching task); its progress comes back as Dask structured events on one topic per engine.
The embedded cluster's processes exit by themselves when the service dies (distributed's
parent-alive pipe), and run at a lower CPU priority than the service (`plan_priority`).
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import logging
import uuid
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from gcs.service import plan_worker
from gcs.service.plan_jobs import PlanJob

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

__all__ = ["WORKER_QUERY_S", "DaskEngine"]

log = logging.getLogger(__name__)

#: How long the workers may take to say which of a stopped job's tasks they still run (s).
WORKER_QUERY_S = 10.0


class DaskEngine:
    """A Dask client (and, without a scheduler address, its embedded cluster)."""

    def __init__(self, *, workers: int, solver: str | None, scheduler: str | None) -> None:
        self._workers = workers
        self._solver = solver
        self._scheduler = scheduler
        self._cluster: LocalCluster | None = None
        self._client: Client | None = None
        self._topic = f"fleetplan-progress-{uuid.uuid4().hex[:12]}"
        self.workers = workers
        """Worker processes planning (known once started)."""
        self._restarts_begun = 0
        self._restarts_done = 0

    @property
    def started(self) -> bool:
        """Connected to a scheduler (and not closed)."""
        return self._client is not None

    @property
    def scheduler_address(self) -> str | None:
        """The scheduler planning runs on (embedded or external), once started."""
        client = self._client
        scheduler = None if client is None else client.scheduler
        return None if scheduler is None else str(scheduler.address)

    async def start(self, on_message: Callable[[dict[str, Any]], None]) -> None:
        """Connect to the scheduler (or start the embedded cluster), follow the progress
        topic (each message to `on_message`), and warm the workers."""
        import dask
        from distributed import Client, LocalCluster

        if self._scheduler:
            client = await Client(self._scheduler, asynchronous=True, timeout=10)
            self.workers = len(client.scheduler_info().get("workers", {})) or 1
        else:
            # A plan that kills its worker (out of memory) would kill the next one too.
            with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
                self._cluster = await LocalCluster(
                    n_workers=self._workers, threads_per_worker=1, processes=True,
                    host="127.0.0.1", scheduler_port=0, dashboard_address=None,
                    asynchronous=True, silence_logs=logging.WARNING,
                )
            client = await Client(self._cluster, asynchronous=True)
        self._client = client

        def on_event(event: tuple[float, dict[str, Any]]) -> None:
            on_message(event[1])

        client.subscribe_topic(self._topic, on_event)
        # Import the planner on every worker now rather than on the first request (at full
        # priority: the service's start waits for it).
        await client.run(plan_worker.warm)
        if self._cluster is not None:  # our own workers share the service's cores
            from gcs.service.plan_priority import LowerPriority

            await client.register_plugin(LowerPriority())

    async def close(self) -> None:
        """Close the client and the embedded cluster (tasks of an external one run on until
        their cancel flag stops them)."""
        client, self._client = self._client, None
        if client is not None:
            with contextlib.suppress(Exception):
                client.unsubscribe_topic(self._topic)
            with contextlib.suppress(Exception):
                closing = client.close(timeout=5)  # an awaitable: the client is asynchronous
                if inspect.isawaitable(closing):
                    await closing
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                closing = self._cluster.close(timeout=10)
                if inspect.isawaitable(closing):
                    await closing
            self._cluster = None

    def _connected(self) -> Client:
        client = self._client
        if client is None:
            raise RuntimeError("the planning engine is not started")
        return client

    def cancel_flag(self, job: PlanJob) -> Any:
        """The job's Dask Event: its tasks stop after their current iteration once it is set."""
        from distributed import Event as DaskEvent

        return DaskEvent(f"{job.key}-cancel", client=self._connected())

    def submit(self, job: PlanJob, scenario: Any, attempt: int = 0) -> tuple[Any, list[Any]]:
        """Submit the job's task(s): its final future, and the futures it depends on (a
        sequence's legs). Small jobs first (priority by estimated work). A later `attempt`
        (the first was killed with a worker the service restarted) gets keys of its own:
        the scheduler may still hold the killed ones."""
        client = self._connected()
        options = {"topic": self._topic, "time_limit_s": job.time_limit_s,
                   "cancel_event": f"{job.key}-cancel"}
        key = job.key if attempt == 0 else f"{job.key}-retry{attempt}"
        if isinstance(scenario, dict):
            return client.submit(plan_worker.run_plan, job.key, scenario, self._solver,
                                 **options, key=key, pure=False, priority=-job.work,
                                 retries=0), []
        legs = [
            client.submit(plan_worker.run_plan, job.key, leg, self._solver, **options, leg=k,
                          key=f"{key}-leg{k}", pure=False, priority=-job.work, retries=0)
            for k, leg in enumerate(scenario.jobs)
        ]
        stitched = client.submit(plan_worker.stitch_sequence, scenario, *legs, key=key,
                                 pure=False, priority=-job.work, retries=0)
        return stitched, legs

    async def workers_running(self, job: PlanJob) -> list[str]:
        """Workers executing one of the job's tasks right now, by their own account (the
        job's `started` events as a fallback when they cannot be asked)."""
        client = self._connected()
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

    async def restart_workers(self, workers: list[str]) -> None:
        """Restart worker processes (through their nannies); logged when they cannot be."""
        client = self._client
        if client is None:
            return
        self._restarts_begun += 1
        try:
            await client.restart_workers(workers, timeout=60, raise_for_error=False)
        except Exception:  # not restartable (no nanny): the task runs on, results dropped
            log.exception("could not restart worker(s) %s", workers)
        finally:
            self._restarts_done += 1

    def restart_mark(self) -> tuple[int, int]:
        """Where the engine's worker restarts stand now (restarts begun, restarts done)."""
        return self._restarts_begun, self._restarts_done

    def restarted_since(self, mark: tuple[int, int]) -> bool:
        """Did a worker restart of this engine's run at some time after `mark` (one under way
        then, or one begun since)? A task that died with its worker meanwhile may have been
        killed by the service's own restart rather than by its plan."""
        begun, done = mark
        return self._restarts_begun != begun or done < begun


def _executing_keys(prefix: str, dask_worker: Any = None) -> list[str]:
    """Keys of the tasks starting with `prefix` that this worker executes (run on workers)."""
    return [str(task.key) for task in dask_worker.state.executing
            if str(task.key).startswith(prefix)]
