"""Progress inside long SCP iterations: `planner.plan(within_iterations=...)` gets an
`IterationProgress` after group QPs (at most once per `PROGRESS_EVERY_S`; zero here, so after
every group), labelled with its method and batch, in order between the iteration records;
the `progress` callback keeps receiving iteration records only."""

from __future__ import annotations

import json

import pytest

import planner
from planner import IterationProgress, IterationRecord
from planner.families.generators import sideways
from planner.options import PlanningOptions
from planner.scp import loop
from tests.paths import EXAMPLES


@pytest.fixture
def every_group(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(loop, "PROGRESS_EVERY_S", 0.0)


def _plan(scenario, **kwargs):
    seen: list[IterationRecord | IterationProgress] = []
    records: list[IterationRecord] = []

    def progress(record: IterationRecord) -> None:
        records.append(record)
        seen.append(record)

    plan = planner.plan(scenario, progress=progress, within_iterations=seen.append, **kwargs)
    return plan, records, seen


def test_reports_inside_iterations_come_between_their_records(every_group: None) -> None:
    scenario = planner.Scenario.from_dict(json.loads((EXAMPLES / "random16.json").read_text()))
    plan, records, seen = _plan(scenario, method="whole")
    assert plan.ok
    assert all(isinstance(r, IterationRecord) for r in records)
    assert records == list(plan.iterations)
    reports = [r for r in seen if isinstance(r, IterationProgress)]
    assert reports, "every group's QP reports with PROGRESS_EVERY_S = 0"
    for report in reports:
        assert 0 <= report.groups_done <= report.groups and report.round >= 1
        assert 1 <= report.largest_group <= 16 and report.separation_rows >= 0
        assert report.qp_solves >= report.groups_done and report.seconds >= 0
        assert report.method == "whole" and report.batch is None
    # a report of iteration k comes after the record of k - 1 and before the record of k
    last_record = -1
    for item in seen:
        if isinstance(item, IterationRecord):
            last_record = item.iteration
        else:
            assert item.iteration == last_record + 1


def test_batches_label_their_reports(every_group: None) -> None:
    _, _, seen = _plan(sideways(16), method="prioritized",
                       options=PlanningOptions(batch_size=4))
    reports = [r for r in seen if isinstance(r, IterationProgress)]
    assert reports and all(r.method == "prioritized" and r.batches == 4 for r in reports)
    assert {r.batch for r in reports} <= {1, 2, 3, 4}


def test_without_the_callback_progress_gets_records_only(every_group: None) -> None:
    got: list[object] = []
    planner.plan(sideways(8), method="whole", progress=got.append)
    assert got and all(isinstance(r, IterationRecord) for r in got)


def test_a_round_with_a_big_group_is_reported_as_it_starts(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The QP of a crowd crossing one point can take minutes: its round is reported before
    it is solved, whatever the interval (PROGRESS_GROUP_VEHICLES); other rounds are not."""
    monkeypatch.setattr(loop, "PROGRESS_EVERY_S", float("inf"))
    monkeypatch.setattr(loop, "PROGRESS_GROUP_VEHICLES", 4)
    _, _, seen = _plan(sideways(16), method="whole")
    reports = [r for r in seen if isinstance(r, IterationProgress)]
    assert reports
    assert all(r.groups_done == 0 and r.largest_group >= 4 for r in reports)
    rounds = {(r.iteration, r.round) for r in reports}
    assert len(rounds) == len(reports)  # one report per round, as it starts
