"""`steps: "auto"`: the planner chooses the shortest horizon (within 10 %) with a verified
plan, reports how, and says so when none exists under `max_horizon`."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

import planner
from planner import Plan, Scenario, ScenarioError
from planner.families.generators import circle_swap, show_sequence
from planner.methods.horizon_search import MAX_PLANS, TOLERANCE, relaxed_steps
from planner.methods.sequence import parse_sequence, plan_sequence, timeline_steps
from planner.model.scenario import DEFAULT_MAX_HORIZON, MAX_STEPS
from planner.scp.solvers import make_solver
from tests.planner.conftest import load_example


def _auto(data: dict[str, Any], **extra: Any) -> dict[str, Any]:
    return {**copy.deepcopy(data), "steps": "auto", **extra}


def _crowded() -> dict[str, Any]:
    """12 vehicles swapping across a small flat circle: the fewest steps the boxes allow
    are too few to pass each other (the search must grow, then bisect)."""
    return circle_swap(12, height_step=0.0, rotation=0.0, radius=2.5)


def _longest_failing(data: dict[str, Any], start: int, chosen: int) -> int:
    """Plan the crowd at every fixed horizon from `start` to the longest one under
    chosen / 1.1 (brute force) and fail naming any that verifies: the shortest verified
    horizon is then longer than that longest one, which is returned (steps), and `chosen`
    is within 10 % of it."""
    longest = math.ceil(chosen / (1 + TOLERANCE)) - 1
    assert start <= longest  # something to scan
    verified = [steps for steps in range(start, longest + 1)
                if planner.plan({**data, "steps": steps}).ok]
    assert verified == [], f"verified at {verified} steps, more than 10 % under {chosen}"
    return longest


@pytest.fixture(scope="module")
def crowded_plan() -> Plan:
    return planner.plan(_auto(_crowded()))


@pytest.fixture(scope="module")
def crowded_failing(crowded_plan: Plan) -> int:
    """The crowd's longest horizon (steps) under the chosen one's 10 % at which no plan
    verifies, nor at any shorter one from the parser's kinematic bound: scanned once."""
    data = _crowded()
    assert crowded_plan.horizon is not None
    return _longest_failing(data, Scenario.from_dict(_auto(data)).steps,
                            crowded_plan.horizon["chosen_steps"])


def test_auto_is_within_ten_percent_of_the_shortest_verified_horizon(crowded_plan,
                                                                     crowded_failing):
    plan = crowded_plan
    block = plan.horizon
    assert plan.ok
    assert block is not None and block["auto"] is True
    chosen = block["chosen_steps"]
    assert plan.scenario.steps == chosen and not plan.scenario.steps_auto
    # no plan verifies from the parser's bound to `crowded_failing`: the shortest verified
    # horizon is longer, and at most the plan's (which verified)
    shortest = crowded_failing + 1  # its lowest possible value
    assert block["lower_bound_steps"] <= shortest
    # (so shortest <= chosen <= 1.1 * shortest: the fixture's failing plans are that check)
    assert shortest <= chosen <= (1 + TOLERANCE) * shortest
    assert block["within_tolerance"] is True
    # the first candidate, 10 % over the bound, failed here: the search grew and closed in
    tried = block["tried"]
    assert tried[0]["steps"] == math.floor(1.1 * block["lower_bound_steps"]) < shortest
    assert tried[0]["status"] != "converged"
    assert 2 <= len(tried) <= MAX_PLANS
    assert {"steps": chosen, "status": "converged"}.items() <= next(
        t for t in tried if t["steps"] == chosen).items()
    assert all(t["status"] != "converged" for t in tried if t["steps"] < chosen)


def test_the_plan_json_carries_the_horizon_and_the_chosen_steps(crowded_plan):
    document = crowded_plan.to_dict()
    assert document["scenario"]["steps"] == crowded_plan.horizon["chosen_steps"]
    assert "max_horizon" not in document["scenario"]
    assert document["horizon"]["max_horizon"] == DEFAULT_MAX_HORIZON
    assert f"horizon {document['scenario']['steps']} steps" in document["message"]
    again = Plan.from_dict(document)
    assert again.horizon == crowded_plan.horizon
    assert again.scenario.steps == crowded_plan.scenario.steps
    assert len(again.vehicles[0].t) == again.scenario.steps + 1


def test_a_fixed_steps_plan_has_a_null_horizon_block():
    plan = planner.plan(load_example("paper-circle2"))
    assert plan.horizon is None
    assert plan.to_dict()["horizon"] is None


def test_a_fleet_that_plans_near_its_bound_takes_one_plan():
    plan = planner.plan(_auto(load_example("paper-circle4")))
    assert plan.ok
    block = plan.horizon
    assert [t["steps"] for t in block["tried"]] == [block["chosen_steps"]]
    bound = block["lower_bound_steps"]
    assert bound < block["chosen_steps"] <= (1 + TOLERANCE) * bound
    # one step under the bound fails: no horizon there verifies
    assert not planner.plan({**load_example("paper-circle4"), "steps": bound - 1}).ok


def test_the_bound_is_where_the_boxes_first_allow_the_farthest_moves():
    spec = Scenario.from_dict(_auto(load_example("paper-circle4")))
    bound = relaxed_steps(spec.assigned(), make_solver(None))
    assert bound is not None and spec.steps <= bound
    first = planner.plan({**load_example("paper-circle4"), "steps": bound - 1})
    assert first.status == "infeasible" and "cannot reach its goal" in first.message


def test_no_verified_plan_under_max_horizon_says_so(crowded_failing):
    data = _crowded()
    failing = crowded_failing  # no plan verifies at this horizon or any shorter one
    too_short = failing * data["dt"]
    plan = planner.plan(_auto(data, max_horizon=too_short))
    assert not plan.ok and plan.status != "converged"
    assert plan.horizon["chosen_steps"] is None
    assert plan.horizon["within_tolerance"] is False
    assert max(t["steps"] for t in plan.horizon["tried"]) == failing
    assert f"no horizon up to max_horizon {too_short:g} s" in plan.message


def test_max_horizon_under_the_kinematic_bound_names_the_field():
    data = _auto(load_example("paper-circle4"), max_horizon=1.0)
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data)
    assert info.value.field == "max_horizon"
    assert "raise max_horizon" in info.value.reason and "vehicles[" in info.value.reason


def test_an_auto_scenario_echoes_auto_and_its_max_horizon():
    spec = Scenario.from_dict(_auto(load_example("paper-circle4"), max_horizon=12))
    echoed = spec.to_dict()
    assert echoed["steps"] == "auto" and echoed["max_horizon"] == 12
    assert spec.max_steps == round(12 / spec.dt)
    assert Scenario.from_dict(echoed).to_dict() == echoed
    default = Scenario.from_dict(_auto(load_example("paper-circle4")))
    assert default.max_horizon == DEFAULT_MAX_HORIZON
    assert default.max_steps == min(MAX_STEPS, math.floor(DEFAULT_MAX_HORIZON / spec.dt))


@pytest.mark.parametrize(
    ("changes", "field", "reason"),
    [
        ({"steps": "fast"}, "steps", '"auto"'),
        ({"steps": "x" * 100}, "steps", "..."),
        ({"steps": 10.5}, "steps", "must be an integer, got 10.5"),
        ({"max_horizon": 20}, "max_horizon", 'applies only with steps "auto"'),
        ({"steps": "auto", "max_horizon": "long"}, "max_horizon", "must be a number"),
        ({"steps": "auto", "max_horizon": -5}, "max_horizon", "must be positive"),
        ({"steps": "auto", "max_horizon": math.inf}, "max_horizon", "finite"),
        ({"steps": "auto", "max_horizon": 1e6}, "max_horizon", "at most 3600 s"),
        ({"steps": "auto", "max_horizon": 0.3}, "max_horizon", "at least 3 steps"),
    ],
)
def test_bad_steps_and_max_horizon_name_the_field(changes, field, reason):
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict({**load_example("paper-circle4"), **changes})
    assert info.value.field == field
    assert reason in info.value.reason


def test_the_bound_covers_every_fixed_trajectory_sample():
    data = _auto(load_example("paper-circle2"))
    data["fixed"] = [{"id": "guest", "positions": [[4.5, 4.5, 2.5]] * 40}]
    spec = Scenario.from_dict(data)
    assert spec.steps == 39
    plan = planner.plan(data)
    assert plan.ok and plan.scenario.steps >= 39


# ------------------------------------------------------------------------ formation sequences


def _auto_sequence(**extra: Any) -> dict[str, Any]:
    """show_sequence(9) with its second leg's duration left to the planner."""
    data = copy.deepcopy(show_sequence(9, seed=2, hold=1.0))
    data["formations"][2]["duration"] = "auto"
    return {**data, **extra}


def test_a_sequence_leg_of_auto_duration_is_planned_at_its_searched_horizon():
    data = _auto_sequence()
    sequence = parse_sequence(data)
    assert sequence.legs[1]["steps"] == "auto" and "max_horizon" not in sequence.legs[1]
    assert sequence.least_steps[0] == sequence.legs[0]["steps"]
    assert timeline_steps(sequence) == sum(sequence.holds) + sum(sequence.least_steps)
    show = plan_sequence(sequence)
    assert show.ok, show.message
    fixed_leg, auto_leg = show.legs
    assert fixed_leg.horizon is None and fixed_leg.scenario.steps == sequence.legs[0]["steps"]
    chosen = auto_leg.horizon["chosen_steps"]
    assert auto_leg.scenario.steps == chosen >= sequence.least_steps[1]
    # the auto leg is shorter than the 30 s the show gave it, and the timeline follows it
    assert chosen * data["dt"] < 30.0
    assert show.accelerations.shape[1] == sum(sequence.holds) + fixed_leg.scenario.steps + chosen
    summary = show.to_plan().sequence
    assert [leg["steps"] for leg in summary["legs"]] == [fixed_leg.scenario.steps, chosen]
    assert "horizon" not in summary["legs"][0]
    assert summary["legs"][1]["horizon"]["chosen_steps"] == chosen


def test_a_sequence_passes_max_horizon_to_its_auto_legs_only():
    sequence = parse_sequence(_auto_sequence(max_horizon=60))
    assert "max_horizon" not in sequence.legs[0]
    assert sequence.legs[1]["max_horizon"] == 60


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        ({"max_horizon": 1.0}, "max_horizon", "formations[2] (an auto duration)"),
        ({"duration": "soon"}, "formations[2].duration", '"auto"'),
    ],
)
def test_bad_auto_legs_name_the_field(change, field, reason):
    data = _auto_sequence()
    if "max_horizon" in change:
        data.update(change)
    else:
        data["formations"][2].update(change)
    with pytest.raises(ScenarioError) as info:
        parse_sequence(data)
    assert info.value.field == field
    assert reason in info.value.reason


def test_max_horizon_without_an_auto_leg_names_the_field():
    data = {**copy.deepcopy(show_sequence(9, seed=2, hold=1.0)), "max_horizon": 60}
    with pytest.raises(ScenarioError) as info:
        parse_sequence(data)
    assert info.value.field == "max_horizon" and "duration" in info.value.reason


def test_boxes_that_allow_no_horizon_plan_the_longest_once_and_say_why():
    data = _auto(load_example("paper-circle4"), max_horizon=8.0)
    data["limits"]["jerk_max"] = [0.05, 0.05, 0.05]  # far too tight for 8 s
    plan = planner.plan(data)
    assert plan.status == "infeasible" and plan.horizon["lower_bound_steps"] is None
    assert [t["steps"] for t in plan.horizon["tried"]] == [40]
    assert "no horizon up to max_horizon 8 s (40 steps of 0.2 s)" in plan.message
    assert "under the jerk bounds" in plan.message
