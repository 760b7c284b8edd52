"""The embedded cluster's planning workers run below the service's CPU priority, restarted
workers too, so a flight on the same cores gets its ticks first."""

from __future__ import annotations

import asyncio
import os

from distributed import Client

from gcs.service.plan_engine import DaskEngine
from gcs.service.plan_priority import PLAN_WORKER_NICENESS


def _niceness() -> int:
    """The niceness of the thread this runs on (a Dask task runs on a worker's task thread)."""
    return os.getpriority(os.PRIO_PROCESS, 0)


def test_embedded_workers_plan_at_lower_priority_even_after_a_restart() -> None:
    async def scenario() -> tuple[int, list[int], list[int]]:
        engine = DaskEngine(workers=1, solver=None, scheduler=None)
        await engine.start(lambda message: None)
        try:
            address = engine.scheduler_address
            assert address is not None
            async with Client(address, asynchronous=True) as client:
                before = await client.gather(
                    [client.submit(_niceness, pure=False, key=f"nice-{k}") for k in range(2)])
                await client.restart_workers(list(client.scheduler_info()["workers"]))
                after = await client.gather(
                    [client.submit(_niceness, pure=False, key=f"again-{k}") for k in range(2)])
            return _niceness(), before, after
        finally:
            await engine.close()

    service, before, after = asyncio.run(scenario())
    assert service < PLAN_WORKER_NICENESS  # the service itself is not lowered
    assert set(before) == {PLAN_WORKER_NICENESS}
    assert set(after) == {PLAN_WORKER_NICENESS}
