"""Planning jobs on a Dask cluster of 2 worker processes: progress, cancel, time limit, the
bounded queue, small jobs beside large ones, store faults, and no worker left behind."""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

import psutil
import pytest
from distributed import Client, LocalCluster
from distributed import Event as DaskEvent

from gcs.errors import ServiceBusy
from gcs.service import plan_runner, plan_worker
from gcs.service.planning import PlanJob, PlanningService
from gcs.service.store import Store
from planner import Scenario
from tests.api.support import example
from tests.service.support import (
    assert_idle,
    done,
    executing,
    fill_the_disk,
    started_service,
    worker_pids,
)
from tests.support.waiting import until, wait_for

pytestmark = pytest.mark.timeout(300)


def scenario(name: str) -> dict[str, Any]:
    return Scenario.from_dict(example(name)).to_dict()


def submit(service: PlanningService, store: Store, name: str, **options: Any) -> PlanJob:
    data = scenario(name)
    row = store.create_mission(data)
    return service.submit(row.id, data, **options)


def workers(cluster: LocalCluster) -> set[str]:
    """Addresses of the workers the scheduler knows now."""
    with Client(cluster.scheduler_address, timeout=10) as client:
        return set(client.scheduler_info()["workers"])


def arms_gone(cluster: LocalCluster) -> bool:
    """No worker process has a child process (auto's forked arms) left, zombie or not."""
    return not any(psutil.Process(pid).children() for pid in worker_pids(cluster).values())


def test_progress_arrives_in_order_and_matches_the_stored_plan(store, cluster) -> None:
    async def scenario_run() -> None:
        service = await started_service(store, cluster)
        try:  # one method: auto's race would also stream the losing method's iterations
            data = scenario("circle16") | {"method": "whole"}
            job = service.submit(store.create_mission(data).id, data)
            outcome = await done(job)
        finally:
            await service.close()
        assert outcome["status"] == "planned", outcome
        row = store.get_mission(job.mission_id, with_plan=True)
        assert row is not None and row.status == "planned" and row.plan_json is not None
        iterations = json.loads(row.plan_json)["iterations"]
        assert [r["iteration"] for r in job.progress] == [r["iteration"] for r in iterations]
        assert [r["cost"] for r in job.progress] == pytest.approx([r["cost"] for r in iterations])
        assert job.worker in workers(cluster)

    asyncio.run(scenario_run())


def test_cancel_stops_the_computation_and_frees_the_worker(store, cluster) -> None:
    async def scenario_run() -> None:
        service = await started_service(store, cluster)
        try:
            job = submit(service, store, "random128")  # auto: two forked arms race
            await asyncio.wait_for(job.started.wait(), 60)
            service.cancel(job.mission_id)
            outcome = await done(job)
            assert outcome["status"] == "failed"
            assert outcome["error"]["reason"] == "cancelled by the operator"
            row = store.get_mission(job.mission_id)
            assert row is not None and row.status == "failed"
            assert row.error == {"field": None, "reason": "cancelled by the operator"}
            # The worker really stopped: both report nothing executing, and no arm of the
            # race is left running (or unreaped) under a worker.
            assert_idle(cluster)
            wait_for(lambda: arms_gone(cluster), "no arm of the race left under a worker",
                     timeout=30.0, poll=0.2)
            small = submit(service, store, "paper-circle4")
            assert (await done(small))["status"] == "planned"
        finally:
            await service.close()

    asyncio.run(scenario_run())


def stubborn_plan(job_id: str, scenario: dict[str, Any], solver: str | None, *,
                  topic: str, **_: Any) -> Any:
    """A task in one very long SCP iteration: it never reaches a point where it checks its
    cancel flag (runs on the worker; imported there by reference). Scenarios of up to 4
    vehicles are planned for real."""
    from distributed import get_worker

    from gcs.service.plan_worker import PlanOutcome, run_plan

    if len(scenario["vehicles"]) <= 4:
        return run_plan(job_id, scenario, solver, topic=topic, **_)

    worker = get_worker()
    worker.log_event(topic, {"job": job_id, "kind": "started", "worker": worker.address})
    time.sleep(120)  # stuck, until its worker is restarted
    return PlanOutcome.failed("ran for two minutes")


def test_a_task_that_ignores_cancel_is_stopped_by_restarting_its_worker(
    store, cluster, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(plan_worker, "run_plan", stubborn_plan)

    async def scenario_run() -> None:
        service = await started_service(store, cluster, cancel_grace_s=0.5)
        try:
            job = submit(service, store, "random128")
            await asyncio.wait_for(job.started.wait(), 60)
            old = (await asyncio.to_thread(worker_pids, cluster))[job.worker]
            service.cancel(job.mission_id, "stop now")
            outcome = await done(job)
            assert outcome["error"]["reason"] == "stop now"

            async def replaced() -> bool:
                now = set((await asyncio.to_thread(worker_pids, cluster)).values())
                return len(now) == 2 and old not in now

            await until(replaced, "a new worker process in the stopped one's place",
                        timeout=60.0, poll=0.2)
        finally:
            await service.close()
        assert_idle(cluster)

    asyncio.run(scenario_run())


def test_a_plan_posted_as_a_cancelled_plans_worker_restarts_is_planned(
    store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The service's own cluster (one worker, no failures allowed): a plan posted right after
    a cancel is queued on the worker restarted to stop the cancelled task, dies with it, and
    is submitted again: it is planned, never 'worker process died'."""
    monkeypatch.setattr(plan_worker, "run_plan", stubborn_plan)

    async def scenario_run() -> None:
        service = PlanningService(store, workers=1, solver=None, cancel_grace_s=0.5)
        await service.start()
        try:
            stuck = submit(service, store, "paper-circle6")  # 6 vehicles: stubborn
            await asyncio.wait_for(stuck.started.wait(), 60)
            service.cancel(stuck.mission_id, "stop now")
            small = submit(service, store, "paper-circle4")  # no wait for the restart
            assert (await done(stuck))["error"]["reason"] == "stop now"
            outcome = await done(small)
            assert outcome["status"] == "planned", outcome
            assert "went with a restarted worker" in caplog.text  # the race was met
        finally:
            await service.close()

    asyncio.run(scenario_run())


def test_time_limit_fails_the_mission_with_the_reason(store, cluster) -> None:
    async def scenario_run() -> None:
        service = await started_service(store, cluster, time_limit_s=30)
        try:
            job = submit(service, store, "random128", time_limit_s=0.05)
            outcome = await done(job)
        finally:
            await service.close()
        reason = "planning exceeded its time limit of 0.05 s"
        assert outcome["error"]["reason"] == reason
        row = store.get_mission(job.mission_id)
        assert row is not None and row.status == "failed" and row.error["reason"] == reason

    asyncio.run(scenario_run())
    assert_idle(cluster)


def test_requested_time_limit_is_bounded_by_the_setting(store, cluster) -> None:
    async def scenario_run() -> None:
        service = await started_service(store, cluster, time_limit_s=30)
        try:
            with pytest.raises(Exception, match="at most 30 s") as info:
                service.job_time_limit(31)
            assert info.value.field == "time_limit"
            assert service.job_time_limit(None) == 30
        finally:
            await service.close()

    asyncio.run(scenario_run())


def patient_plan(job_id: str, scenario: dict[str, Any], solver: str | None, *,
                 topic: str, cancel_event: str | None = None, **_: Any) -> Any:
    """A task that runs until told to stop, looking every 50 ms with the check the planner
    makes after each SCP iteration (runs on the worker; imported there by reference).
    Scenarios of up to 4 vehicles are planned for real."""
    from distributed import get_worker

    from gcs.service.plan_worker import PlanOutcome, run_plan, stop_check

    if len(scenario["vehicles"]) <= 4:
        return run_plan(job_id, scenario, solver, topic=topic, cancel_event=cancel_event, **_)

    worker = get_worker()
    worker.log_event(topic, {"job": job_id, "kind": "started", "worker": worker.address})
    wait_for(stop_check(cancel_event), "the job to be cancelled", timeout=120.0)
    return PlanOutcome.failed("planning was cancelled", stopped=True)


def test_a_full_queue_is_refused_and_small_jobs_pass_large_ones(
    store, cluster, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Large jobs that never end by themselves (only when cancelled): the outcome cannot
    # depend on timing, and stopping them needs no worker restart.
    monkeypatch.setattr(plan_worker, "run_plan", patient_plan)

    async def scenario_run() -> None:
        service = await started_service(store, cluster, queue_max=3)
        try:
            large = [submit(service, store, "random128") for _ in range(2)]
            small = submit(service, store, "paper-circle4")
            with pytest.raises(ServiceBusy, match="plan_queue_max"):
                service.check_capacity()
            with pytest.raises(ServiceBusy):
                submit(service, store, "paper-circle2")
            # Two workers, two large jobs ahead of it: the small one still runs first.
            assert (await done(small))["status"] == "planned"
            assert not any(job.done.is_set() for job in large)
            for job in large:
                service.cancel(job.mission_id)
            for job in large:
                outcome = await done(job)
                assert outcome["error"]["reason"] == "cancelled by the operator"
            service.check_capacity()  # room again
        finally:
            await service.close()

    asyncio.run(scenario_run())
    assert_idle(cluster)


def test_a_task_dropped_as_it_starts_still_finds_its_cancel_flag_set(
    store, cluster, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Cancelled before its `started` event arrived, the job ends at once; the task may
    still begin on a busy worker moments later, so its cancel flag stays set while the
    service looks for it (then it is cleared: nothing is left on the scheduler)."""
    monkeypatch.setattr(plan_worker, "run_plan", patient_plan)

    async def scenario_run() -> tuple[bool, bool]:
        service = await started_service(store, cluster)
        try:
            job = submit(service, store, "random128")
            service.cancel(job.mission_id)  # before any worker said it started
            outcome = await done(job)
            assert outcome["error"]["reason"] == "cancelled by the operator"
            async with Client(cluster.scheduler_address, asynchronous=True) as client:
                flag = DaskEvent(f"{job.key}-cancel", client=client)
                set_after_done = await flag.is_set()
                await service.close()  # waits for the stop to finish its looks
                set_after_close = await flag.is_set()
            return set_after_done, set_after_close
        finally:
            await service.close()

    set_after_done, set_after_close = asyncio.run(scenario_run())
    assert set_after_done
    assert not set_after_close
    assert_idle(cluster)


def test_a_task_whose_future_is_dropped_stops_by_itself_with_no_flag_set(cluster) -> None:
    """A task the scheduler released (its future dropped while it ran) stops at its next
    look, even when its cancel flag is never set: it cannot run on for its whole length
    however late the flag is looked at or cleared."""
    with Client(cluster.scheduler_address, timeout=10) as client:
        future = client.submit(patient_plan, "dropped", scenario("random128"), None,
                               topic="dropped-task", cancel_event="a-flag-nobody-sets",
                               key="dropped-task", pure=False)
        wait_for(lambda: any(executing(cluster).values()), "the task to start", timeout=60.0)
        future.cancel()
    # patient_plan would run 120 s by itself.
    assert_idle(cluster, timeout=60)


def test_a_plan_the_disk_cannot_hold_fails_the_mission_with_the_reason(store, cluster) -> None:
    async def scenario_run() -> None:
        service = await started_service(store, cluster)
        try:
            data = scenario("circle16")
            row = store.create_mission(data)
            fill_the_disk(store)
            job = service.submit(row.id, data)
            outcome = await done(job)
        finally:
            await service.close()
        assert outcome["status"] == "failed"
        assert "could not be stored" in outcome["error"]["reason"]
        assert "full" in outcome["error"]["reason"]
        stored = store.get_mission(row.id)
        assert stored is not None and stored.status == "failed"
        assert stored.error == outcome["error"]

    asyncio.run(scenario_run())


def test_a_refused_failure_write_is_retried_until_stored(
    store, cluster, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(plan_runner, "STORE_RETRY_S", 0.05)
    real_fail = store.fail_planning
    refusals = {"finish": 0, "fail": 0}

    def finish(*args: Any, **kwargs: Any) -> bool:
        refusals["finish"] += 1
        raise OSError("disk full")

    def fail(*args: Any, **kwargs: Any) -> bool:
        if refusals["fail"] < 3:
            refusals["fail"] += 1
            raise OSError("disk full")
        return real_fail(*args, **kwargs)

    monkeypatch.setattr(store, "finish_planning", finish)
    monkeypatch.setattr(store, "fail_planning", fail)

    async def scenario_run() -> str:
        service = await started_service(store, cluster)
        try:
            job = submit(service, store, "paper-circle4")
            assert (await done(job))["status"] == "failed"
            await until(lambda: (row := store.get_mission(job.mission_id)) is not None
                        and row.status != "planning", "the failure stored", timeout=30.0)
        finally:
            await service.close()
        return job.mission_id

    mission_id = asyncio.run(scenario_run())
    row = store.get_mission(mission_id)
    assert row is not None and row.status == "failed"
    assert row.error is not None and "OSError: disk full" in row.error["reason"]
    assert refusals == {"finish": 1, "fail": 3}


def test_the_embedded_cluster_leaves_no_process_behind(store) -> None:
    me = psutil.Process()
    before = {p.pid for p in me.children(recursive=True)}

    async def scenario_run() -> list[psutil.Process]:
        service = PlanningService(store, workers=2, solver=None)
        await service.start()
        try:
            # multiprocessing's resource tracker is one per parent process, shared by
            # everything it spawns, and exits with it: not a worker.
            spawned = [p for p in me.children(recursive=True) if p.pid not in before
                       and "resource_tracker" not in " ".join(p.cmdline())]
            job = submit(service, store, "paper-circle4")
            assert (await done(job))["status"] == "planned"
        finally:
            await service.close()
        return spawned

    spawned = asyncio.run(scenario_run())
    assert len(spawned) >= 2  # the 2 worker processes (their nannies run in this process)
    _, alive = psutil.wait_procs(spawned, timeout=20)
    assert [p.cmdline() for p in alive] == []
