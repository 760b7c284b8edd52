"""Formation sequences as planning jobs: one Dask task per leg on a 2-worker cluster, progress
per leg, the stitched plan stored, and cancel stopping every leg."""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

import pytest

from gcs.service import plan_worker
from gcs.service.planning import PlanJob
from planner import Plan
from planner.families.generators import show_formations, show_sequence
from planner.methods.sequence import parse_sequence, timeline_scenario
from tests.service.support import assert_idle, done, started_service, worker_pids
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(300)


def submit_sequence(service: Any, db: Any, data: dict[str, Any], **options: Any
                    ) -> PlanJob:
    sequence = parse_sequence(data)
    row = db.create_mission(timeline_scenario(sequence).to_dict())
    return service.submit_sequence(row.id, sequence, **options)


def _planned(store, cluster, data: dict) -> tuple[Any, Plan]:
    """Plan the sequence `data` through the engine; its job, and the stored plan read back
    (asserted planned and ok)."""

    async def scenario_run() -> Any:
        service = await started_service(store, cluster)
        try:
            job = submit_sequence(service, store, data)
            outcome = await done(job)
        finally:
            await service.close()
        assert outcome["status"] == "planned" and outcome["plan_ok"] is True, outcome
        return job

    job = asyncio.run(scenario_run())
    row = store.get_mission(job.mission_id, with_plan=True)
    assert row is not None and row.plan_json is not None
    return job, Plan.from_dict(json.loads(row.plan_json))


def test_legs_run_as_tasks_with_progress_per_leg_and_the_stitched_plan_stored(store, cluster
                                                                             ) -> None:
    data = show_sequence(9, seed=4, hold=1.0)
    data["assignment"] = "fixed"  # crossing lines: a few SCP iterations per leg
    data["method"] = "whole"  # one method per leg: auto's race streams the loser's too
    job, plan = _planned(store, cluster, data)
    assert all(leg["method"] == "whole" for leg in parse_sequence(data).legs)
    assert plan.ok and plan.sequence is not None
    assert plan.scenario.horizon == pytest.approx(3 * 1.0 + 2 * 30.0)
    # Every leg reported its iterations, tagged with the leg, in order within the leg.
    legs = plan.sequence["legs"]
    for k, leg in enumerate(legs):
        mine = [r["iteration"] for r in job.progress if r.get("leg") == k]
        assert mine == list(range(leg["iterations"] + 1)), (k, mine)
    assert {r["leg"] for r in job.progress} == {0, 1}
    assert job.ends_seen == 2


def test_a_five_formation_show_plans_its_legs_in_parallel_and_verifies_stitched(
        store, cluster) -> None:
    """Grid, sphere, torus, cube, carpet (free assignment): four legs as tasks on the two
    workers, then the stitch; the stored plan verifies again from its trajectories."""
    from planner.verification.verify import refusal

    data = show_formations(16, seed=1, hold=1.0)
    job, plan = _planned(store, cluster, data)
    assert job.ends_seen == 4 and {r["leg"] for r in job.progress} == {0, 1, 2, 3}
    assert plan.sequence is not None
    assert [f["name"] for f in plan.sequence["formations"]] == [
        "grid", "sphere", "torus", "cube", "carpet"]
    assert [leg["status"] for leg in plan.sequence["legs"]] == ["converged"] * 4
    legs = sum(f["duration"] for f in data["formations"][1:])
    assert plan.scenario.horizon == pytest.approx(5 * 1.0 + legs)
    assert plan.verification is not None and plan.verification.verified
    assert refusal(plan) is None  # checked anew on the stitched trajectories


def test_cancel_stops_every_leg_and_frees_the_workers(store, cluster) -> None:
    data = show_sequence(64, seed=1, hold=1.0)
    data["assignment"] = "fixed"  # tens of seconds per leg on this machine

    async def scenario_run() -> None:
        service = await started_service(store, cluster)
        try:
            job = submit_sequence(service, store, data)
            await asyncio.wait_for(job.started.wait(), 60)
            service.cancel(job.mission_id)
            outcome = await done(job)
            assert outcome["status"] == "failed"
            assert outcome["error"]["reason"] == "cancelled by the operator"
            row = store.get_mission(job.mission_id)
            assert row is not None and row.status == "failed"
            assert_idle(cluster)
        finally:
            await service.close()

    asyncio.run(scenario_run())


def stubborn_leg(job_id: str, scenario: dict[str, Any], solver: str | None, *, topic: str,
                 leg: int | None = None, **_: Any) -> dict[str, Any]:
    """A leg stuck in one endless SCP iteration: it never checks its cancel flag (runs on
    the worker, imported there by reference)."""
    from distributed import get_worker

    worker = get_worker()
    worker.log_event(topic, {"job": job_id, "kind": "started", "leg": leg,
                             "worker": worker.address})
    time.sleep(120)  # stuck, until its worker is restarted
    return {"error": {"field": None, "reason": "ran for two minutes"}}


def test_legs_that_ignore_cancel_have_every_worker_restarted(store, cluster, monkeypatch
                                                             ) -> None:
    monkeypatch.setattr(plan_worker, "run_plan", stubborn_leg)
    data = show_sequence(9, seed=4, hold=1.0)

    async def scenario_run() -> None:
        service = await started_service(store, cluster, cancel_grace_s=0.5)
        try:
            job = submit_sequence(service, store, data)
            await until(lambda: len(job.running) >= 2, "two legs running", timeout=60.0,
                        poll=0.1)
            assert len(set(job.running.values())) == 2, job.running  # a leg on each worker
            stuck = set((await asyncio.to_thread(worker_pids, cluster)).values())
            service.cancel(job.mission_id, "stop now")
            outcome = await done(job)
            assert outcome["error"]["reason"] == "stop now"
            # Both replaced by new processes (a new worker may get a freed port back, so
            # processes are told apart by their pid, not their address).
            async def replaced() -> bool:
                now = set((await asyncio.to_thread(worker_pids, cluster)).values())
                return len(now) == 2 and not (stuck & now)

            await until(replaced, "both stuck workers replaced by new processes",
                        timeout=90.0, poll=0.2,
                        detail=lambda: (stuck, set(worker_pids(cluster).values())))
        finally:
            await service.close()

    asyncio.run(scenario_run())


def test_the_time_limit_stops_a_sequence(store, cluster) -> None:
    data = show_sequence(64, seed=1, hold=1.0)
    data["assignment"] = "fixed"  # several SCP iterations of about a second per leg

    async def scenario_run() -> None:
        service = await started_service(store, cluster)
        try:
            job = submit_sequence(service, store, data, time_limit_s=0.2)
            outcome = await done(job)
            assert outcome["status"] == "failed"
            assert "time limit of 0.2 s" in outcome["error"]["reason"]
            row = store.get_mission(job.mission_id)
            assert row is not None and row.status == "failed"
            assert_idle(cluster)
        finally:
            await service.close()

    asyncio.run(scenario_run())


def test_the_stitched_plan_json_is_to_dict_written_from_the_arrays() -> None:
    """The stitch task's JSON (written from the arrays) is the document of `Plan.to_dict()`,
    number for number, and a non-finite value still becomes null."""
    import dataclasses

    import numpy as np
    import orjson

    from planner.methods.sequence import plan_sequence

    flyable = plan_sequence(show_formations(12, seed=3, hold=1.0)).to_plan()
    assert json.loads(plan_worker.plan_json(flyable)) == json.loads(
        orjson.dumps(flyable.to_dict()))
    first = flyable.vehicles[0]
    thrust = first.thrust.copy()
    thrust[1] = np.nan
    broken = dataclasses.replace(flyable, vehicles=(dataclasses.replace(first, thrust=thrust),
                                                    *flyable.vehicles[1:]))
    assert json.loads(plan_worker.plan_json(broken))["vehicles"][0]["thrust"][1] is None
