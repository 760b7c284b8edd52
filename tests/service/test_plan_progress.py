"""A job's progress summary (`PlanJob.summary`, `planning_summary`): iterations so far, the
report from inside the iteration under way (cleared by that iteration's record), and the time
left in prioritized batches at the mean time of those done; `working` events to listeners."""

from __future__ import annotations

import asyncio

import pytest

from gcs.service.plan_jobs import PlanJob
from gcs.service.plan_progress import planning_summary

RECORD = {"iteration": 1, "cost": 10.0, "cost_change": 1.0, "separation_rows": 4,
          "qp_solves": 1, "groups": 1, "seconds": 0.1, "largest_group": 2,
          "method": "prioritized", "batch": 1, "batches": 4}
WORKING = {"iteration": 1, "round": 1, "groups_done": 3, "groups": 9, "separation_rows": 40,
           "largest_group": 5, "qp_solves": 3,
           "seconds": 2.0, "method": "prioritized", "batch": 3, "batches": 4}


def test_batches_left_are_estimated_at_the_mean_time_of_those_done() -> None:
    summary = planning_summary([RECORD], WORKING, 30.0)
    # batch 3 under way: 2 done in 30 s, 2 left -> 30 s
    assert summary["batches"] == {"done": 2, "total": 4, "remaining_s": 30.0}
    assert summary["working"] == WORKING and summary["last"] == RECORD
    assert summary["iterations"] == 1 and summary["elapsed_s"] == 30.0


@pytest.mark.parametrize(("progress", "working", "batches"), [
    ([], None, None),  # nothing yet
    ([{**RECORD, "batch": None, "batches": None}], None, None),  # the whole fleet: no measure
    ([RECORD], None, {"done": 0, "total": 4, "remaining_s": None}),  # none done: no estimate
])
def test_no_estimate_without_a_measure(progress, working, batches) -> None:
    assert planning_summary(progress, working, 12.0)["batches"] == batches


def test_a_job_reports_work_inside_an_iteration_until_its_record_arrives() -> None:
    async def scenario() -> list[tuple[str, object]]:
        job = PlanJob.new("m1", work=1, time_limit_s=60)
        job.on_message({"kind": "started", "worker": "tcp://w"})
        job.on_message({"kind": "iteration", "record": RECORD})
        seen: list[tuple[str, object]] = []

        async def follow() -> None:
            async for event in job.events():
                seen.append(event)

        follower = asyncio.ensure_future(follow())
        await asyncio.sleep(0)
        job.on_message({"kind": "working", "record": WORKING})
        assert job.summary()["working"] == WORKING
        assert job.summary()["elapsed_s"] is not None
        job.on_message({"kind": "iteration", "record": {**RECORD, "iteration": 2,
                                                        "batch": 3}})
        assert job.summary()["working"] is None and job.summary()["iterations"] == 2
        job.finish({"status": "planned"})
        await asyncio.wait_for(follower, 5)
        return seen

    seen = asyncio.run(scenario())
    kinds = [kind for kind, _ in seen]
    assert kinds == ["iteration", "working", "iteration", "done"]
    working = seen[1][1]
    assert isinstance(working, dict) and working["working"] == WORKING
    assert working["batches"]["total"] == 4
