"""`auto`: the stage table, the race of prioritized batches against the whole fleet in forked
processes (`planner.methods.portfolio`, `planner.methods.race`), and what the plan records of it."""

from __future__ import annotations

import json
import os
import signal
import time
from collections.abc import Callable, Iterator
from typing import Any

import psutil
import pytest

import planner.methods.portfolio as portfolio
import planner.methods.prioritized as prioritized
import planner.methods.stages as stages
from planner import plan
from planner.errors import ScenarioError
from planner.families.generators import sideways
from planner.methods.race import race
from planner.model.scenario import Scenario
from planner.options import PlanningOptions
from planner.result import IterationRecord, Plan, PlanStatus
from planner.scp.loop import ScpOutcome
from tests.paths import EXAMPLES
from tests.support.descriptors import pipes
from tests.support.waiting import wait_for


def _outcomes(result: Plan) -> dict[str, str]:
    return {a.method: a.outcome for a in result.attempts}


Check = Callable[[], bool]


def _children() -> set[int]:
    return {child.pid for child in psutil.Process().children()}


@pytest.fixture
def reaped() -> Iterator[Check]:
    """A check that every arm forked since the test began was reaped (a killed one by a
    thread: it is given a moment); processes started before (a Dask cluster) are not arms."""
    before = _children()

    def check() -> bool:
        return wait_for(lambda: not _children() - before, "every forked arm reaped",
                        timeout=30.0, detail=lambda: _children() - before)

    yield check


@pytest.fixture
def race_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """No head start: every fleet where batches apply races."""
    monkeypatch.setattr(portfolio, "HEAD_START_MAX_VEHICLES", 0)


# ---------------------------------------------------------------- the race itself


def test_the_first_accepted_result_wins_and_the_other_arm_is_killed_and_reaped(
        reaped: Check) -> None:
    def slow(send: Any) -> int:
        time.sleep(60)
        return 2

    results = race([("slow", slow), ("quick", lambda send: 1)], lambda value: value == 1)
    assert [(r.name, r.value, r.cancelled) for r in results] == [
        ("slow", None, True), ("quick", 1, False)]
    assert reaped()


def test_a_result_not_accepted_waits_for_the_other_arm() -> None:
    def later(send: Any) -> int:
        time.sleep(0.2)
        return 2

    results = race([("first", lambda send: 1), ("later", later)], lambda value: value == 2)
    assert [(r.value, r.cancelled) for r in results] == [(1, False), (2, False)]


def test_an_arm_that_raises_or_dies_reports_why() -> None:
    def raises(send: Any) -> None:
        raise ValueError("no luck")

    def dies(send: Any) -> None:
        os.kill(os.getpid(), signal.SIGKILL)

    results = race([("raises", raises), ("dies", dies)], lambda value: True)
    assert results[0].error == "ValueError: no luck"
    assert results[1].error == f"its process was killed by signal {int(signal.SIGKILL)}"
    assert all(r.value is None and not r.cancelled for r in results)


def test_an_arm_that_cannot_start_is_reported_and_leaves_no_descriptor(monkeypatch) -> None:
    """A fork refused (no process to be had) fails that arm only, and closes its pipe."""
    import os

    import planner.methods.race as race_module

    real_fork, forks = os.fork, []

    def fork() -> int:
        forks.append(1)
        if len(forks) == 1:
            raise OSError(11, "Resource temporarily unavailable")
        return real_fork()

    monkeypatch.setattr(race_module.os, "fork", fork)
    before = pipes()  # (the worker's other threads open and close sockets meanwhile)
    results = race([("refused", lambda send: 1), ("started", lambda send: 2)], lambda v: True)
    assert results[0].error == "could not start: [Errno 11] Resource temporarily unavailable"
    assert results[0].value is None and results[1].value == 2
    assert pipes() == before


def test_progress_is_forwarded_in_order_labelled_by_arm() -> None:
    def counts(send: Any) -> str:
        for n in range(5):
            send(n)
        return "done"

    seen: list[tuple[str, Any]] = []
    race([("a", counts)], lambda value: True, seen.append)
    assert seen == [("a", n) for n in range(5)]


def test_an_exception_from_progress_kills_every_arm(reaped: Check) -> None:
    """Ctrl-C or a job's cancel arrives through the progress callback: both arms die."""
    def talks(send: Any) -> None:
        send("hello")
        time.sleep(60)

    def stop(message: Any) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        race([("a", talks), ("b", talks)], lambda value: True, stop)
    assert reaped()


# ---------------------------------------------------------------- the stage table


def test_whole_declines_batches_and_records_every_stage() -> None:
    result = plan(sideways(8), method="whole")
    assert result.ok and result.method == "whole"
    assert [(a.method, a.outcome) for a in result.attempts] == [
        ("separated_first", "declined"), ("dodge", "declined"), ("whole", "won")]
    assert all(r.method == "whole" for r in result.iterations)


def test_free_assignment_takes_a_separated_optimum_without_the_loop() -> None:
    result = plan(sideways(8) | {"assignment": "free"})
    assert result.ok and result.method == "separated_first" and len(result.iterations) == 1
    assert [(a.method, a.outcome) for a in result.attempts] == [("separated_first", "won")]


def test_batches_decline_free_assignment_and_obstacles_the_separated_optimum() -> None:
    data = json.loads((EXAMPLES / "pillar-circle8.json").read_text()) | {"assignment": "free"}
    result = plan(data)
    assert result.ok and result.method == "whole"
    assert [(a.method, a.outcome) for a in result.attempts] == [
        ("separated_first", "declined"), ("head_start", "declined"),
        ("prioritized", "declined"), ("dodge", "declined"), ("whole", "won")]
    assert "free assignment" in result.attempts[2].reason


def test_a_fleet_that_fits_one_batch_is_planned_whole_in_process() -> None:
    result = plan(sideways(2), method="auto")  # moving as one: batches of two
    assert result.ok and result.method == "whole"
    assert _outcomes(result)["prioritized"] == "declined"
    assert next(a.reason for a in result.attempts
                if a.method == "prioritized") == "2 vehicles fit in one batch of 2"


def test_a_small_fleet_gets_the_whole_fleet_in_process_first() -> None:
    result = plan(json.loads((EXAMPLES / "paper-circle4.json").read_text()))
    assert result.ok
    head = result.attempts[1]
    assert head.method == "head_start" and head.outcome in ("won", "failed")
    if head.outcome == "won":
        assert result.method == "whole" and len(result.attempts) == 2


def test_the_method_argument_overrides_the_scenarios_and_is_echoed() -> None:
    data = sideways(8) | {"method": "whole"}
    result = plan(data, method="prioritized")
    assert result.method == "prioritized" and result.scenario.method == "prioritized"
    assert result.to_dict()["scenario"]["method"] == "prioritized"
    assert plan(data).scenario.method == "whole"


@pytest.mark.parametrize("value", ["fastest", 3, None])
def test_a_bad_method_is_refused_naming_the_field(value: Any) -> None:
    with pytest.raises(ScenarioError) as caught:
        Scenario.from_dict(sideways(4) | {"method": value})
    assert caught.value.field == "method"
    assert "must be one of 'auto', 'whole', 'prioritized'" in caught.value.reason


def test_the_plan_status_strings_are_the_enums() -> None:
    assert [s.value for s in PlanStatus] == ["converged", "max_iterations", "infeasible",
                                             "unverified"]
    result = plan(sideways(4), method="whole")
    assert result.status == PlanStatus.CONVERGED and type(result.to_dict()["status"]) is str


# ---------------------------------------------------------------- the portfolio


@pytest.mark.usefixtures("race_at_once")
def test_when_batches_fail_the_whole_fleet_wins(
        reaped: Check, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(stages, "plan_batches", lambda *a, **k: prioritized.NOT_CONVERGED)
    seen: list[IterationRecord] = []
    result = plan(sideways(8), progress=seen.append)
    assert result.ok and result.method == "whole"
    outcomes = _outcomes(result)
    assert (outcomes["prioritized"], outcomes["whole"]) == ("failed", "won")
    assert next(a.reason for a in result.attempts
                if a.method == "prioritized") == prioritized.NOT_CONVERGED
    assert seen and {r.method for r in seen} == {"whole"}
    assert reaped()


@pytest.mark.usefixtures("race_at_once")
def test_when_the_whole_fleet_is_slow_the_batches_win_and_it_is_cancelled(
        reaped: Check, monkeypatch: pytest.MonkeyPatch) -> None:
    def stuck(*args: Any, **kwargs: Any) -> ScpOutcome:
        time.sleep(120)
        raise AssertionError("never reached: the arm is killed")

    monkeypatch.setattr(stages, "run_scp", stuck)  # the whole fleet's loop, not the batches'
    seen: list[IterationRecord] = []
    result = plan(sideways(8), progress=seen.append)
    assert result.ok and result.method == "prioritized"
    assert "prioritized batches" in result.message
    outcomes = _outcomes(result)
    assert (outcomes["prioritized"], outcomes["whole"]) == ("won", "cancelled")
    cancelled = next(a for a in result.attempts if a.outcome == "cancelled")
    assert cancelled.reason == "the prioritized plan came first" and cancelled.seconds > 0
    assert seen and {r.method for r in seen} == {"prioritized"}
    assert all(r.method == "prioritized" for r in result.iterations)
    assert reaped()


@pytest.fixture
def whole_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    """The whole fleet's SCP ends without converging (the batches' loop is untouched)."""
    real = stages.run_scp

    def fails(*args: Any, **kwargs: Any) -> ScpOutcome:
        outcome = real(*args, **kwargs)
        outcome.status = PlanStatus.MAX_ITERATIONS
        return outcome

    monkeypatch.setattr(stages, "run_scp", fails)


@pytest.mark.usefixtures("race_at_once", "whole_fails")
def test_when_the_whole_fleet_fails_the_batches_plan_it() -> None:
    result = plan(sideways(8))
    assert result.ok and result.method == "prioritized"
    assert _outcomes(result)["prioritized"] == "won"
    assert _outcomes(result)["whole"] in ("failed", "cancelled")


@pytest.mark.usefixtures("race_at_once", "whole_fails")
def test_when_both_fail_the_whole_fleets_plan_is_returned_and_says_so(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(stages, "plan_batches", lambda *a, **k: prioritized.NOT_CONVERGED)
    result = plan(sideways(8))
    assert not result.ok and result.status == "max_iterations" and result.method == "whole"
    assert (_outcomes(result)["prioritized"], _outcomes(result)["whole"]) == ("failed", "failed")


@pytest.mark.usefixtures("race_at_once")
def test_a_cancel_from_progress_stops_both_arms(
        reaped: Check, monkeypatch: pytest.MonkeyPatch) -> None:
    class Stop(Exception):
        pass

    def stop(record: IterationRecord) -> None:
        raise Stop

    with pytest.raises(Stop):
        plan(sideways(8), progress=stop)
    assert reaped()


def test_the_batch_setting_reaches_the_batches_arm() -> None:
    result = plan(sideways(8), options=PlanningOptions(batch_size=4), method="prioritized")
    assert "batches of up to 4 vehicles" in result.message


def test_an_old_plan_without_method_or_attempts_still_loads() -> None:
    doc = plan(sideways(4), method="whole").to_dict()
    del doc["method"], doc["attempts"]
    for record in doc["iterations"]:
        del record["method"]
    old = Plan.from_dict(doc)
    assert old.method is None and old.attempts == () and old.iterations[0].method is None
    again = Plan.from_dict(plan(sideways(4), method="whole").to_dict())
    assert again.method == "whole" and again.attempts[-1].outcome == "won"


def test_a_sequence_passes_its_method_to_every_leg() -> None:
    from planner.methods.sequence import parse_sequence

    data = {"name": "s", "dt": 0.2, "min_separation": 1.0, "method": "prioritized",
            "limits": {"position_min": [0, 0, 0], "position_max": [10, 10, 3]},
            "vehicles": ["a", "b"],
            "formations": [{"positions": [[1, 1, 1], [3, 1, 1]]},
                           {"positions": [[1, 5, 1], [3, 5, 1]], "duration": 6.0}]}
    assert [leg["method"] for leg in parse_sequence(data).legs] == ["prioritized"]
    with pytest.raises(ScenarioError) as caught:
        parse_sequence(data | {"method": "fastest"})
    assert caught.value.field == "method"
