"""Helpers of the service tests."""

from __future__ import annotations

import asyncio
import os
from typing import Any

from distributed import Client, LocalCluster
from sqlalchemy import event

from gcs.service.planning import PlanJob, PlanningService
from gcs.service.store import Store
from tests.support.waiting import wait_for

__all__ = ["assert_idle", "done", "executing", "fill_the_disk", "started_service",
           "worker_pids"]


def fill_the_disk(store: Store) -> None:
    """Make the SQLite file unable to grow (SQLITE_FULL), as a full disk would."""

    def cap(connection: Any, _record: Any) -> None:
        cursor = connection.cursor()
        pages = cursor.execute("PRAGMA page_count").fetchone()[0]
        cursor.execute(f"PRAGMA max_page_count={pages}")
        cursor.close()

    event.listen(store.engine, "connect", cap)
    store.engine.dispose()


async def started_service(store: Store, cluster: LocalCluster, **options: Any
                          ) -> PlanningService:
    service = PlanningService(store, workers=2, solver=None,
                              scheduler=cluster.scheduler_address, **options)
    await service.start()
    return service


async def done(job: PlanJob, timeout: float = 240.0) -> dict[str, Any]:
    await asyncio.wait_for(job.done.wait(), timeout)
    assert job.outcome is not None
    return job.outcome


def executing(cluster: LocalCluster) -> dict[str, int]:
    """Tasks each worker process is executing right now (its own view, not the scheduler's)."""
    with Client(cluster.scheduler_address, timeout=10) as client:
        # A worker being restarted cannot answer: it is left out (assert_idle waits for two).
        return client.run(lambda dask_worker: dask_worker.state.executing_count,
                          on_error="ignore")


def worker_pids(cluster: LocalCluster) -> dict[str, int]:
    """Process id of each worker that answers, by address (a restarted worker may get a freed
    port back, so processes are told apart by pid)."""
    with Client(cluster.scheduler_address, timeout=10) as client:
        return client.run(os.getpid, on_error="ignore")


def assert_idle(cluster: LocalCluster, timeout: float = 180.0) -> None:
    """Both workers are up and execute nothing (a restarted worker has a new address), within
    `timeout` s."""
    def idle() -> bool:
        counts = executing(cluster)
        return len(counts) == 2 and not any(counts.values())

    wait_for(idle, "both workers up and idle", timeout, detail=lambda: executing(cluster))
