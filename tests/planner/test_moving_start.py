"""Planning from a moving state: vehicles' start_velocity and start_acceleration."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

import planner
from planner.errors import ScenarioError
from planner.scp.loop import ScpOptions
from planner.verification.verify import refusal, verify
from tests.planner.conftest import load_example


def _moving(data: dict, velocities: list, accelerations: list | None = None) -> dict:
    out = copy.deepcopy(data)
    for n, vehicle in enumerate(out["vehicles"]):
        vehicle["start_velocity"] = velocities[n % len(velocities)]
        if accelerations is not None:
            vehicle["start_acceleration"] = accelerations[n % len(accelerations)]
    return out


def test_a_scenario_without_a_start_state_is_unchanged(paper4) -> None:
    """Scenarios that say nothing of a start state echo no such keys (the contract only
    grows) and start at rest."""
    scenario = planner.Scenario.from_dict(paper4)
    assert scenario.start_velocities is None and scenario.start_accelerations is None
    assert all(set(v) == {"id", "start", "goal"} for v in scenario.to_dict()["vehicles"])
    assert not scenario.initial_velocities.any()


@pytest.mark.parametrize("dual", [True, False])
def test_plan_from_a_moving_state_meets_its_boundary_conditions(paper4, dual: bool) -> None:
    """The plan starts with each vehicle's start velocity, its first jerk is measured from
    its start acceleration, and it is verified; the dual and the primal QPs agree."""
    data = _moving(paper4, [[0.3, 0.2, -0.1], [-0.4, 0.0, 0.2]],
                   [[0.5, -0.3, 0.2], [0.0, 1.0, -0.5]])
    plan = planner.plan(data, options=ScpOptions(dual=dual))
    assert plan.ok, plan.problems()
    scenario = plan.scenario
    velocities = plan.velocities()
    np.testing.assert_allclose(velocities[:, 0], scenario.initial_velocities, atol=1e-6)
    jerk0 = np.stack([v.jerk[0] for v in plan.vehicles])
    expected = (plan.accelerations()[:, 0] - scenario.initial_accelerations) / scenario.dt
    np.testing.assert_allclose(jerk0, expected, atol=1e-9)
    assert np.all(np.abs(jerk0) <= scenario.limits.jerk_max + 1e-5)
    assert plan.verification.boundary_error["start_velocity"] < 1e-6
    # the plan JSON carries the start state and reads back the same
    again = planner.Plan.from_dict(json.loads(json.dumps(plan.to_dict())))
    np.testing.assert_array_equal(again.scenario.initial_velocities, scenario.initial_velocities)
    np.testing.assert_array_equal(again.scenario.initial_accelerations,
                                  scenario.initial_accelerations)
    assert again.scenario.to_dict() == scenario.to_dict()


def test_the_same_plan_is_cheaper_moving_than_at_rest() -> None:
    """Moving towards its goal already, a vehicle needs less thrust than from rest: the
    start velocity is used, not ignored."""
    data = load_example("paper-circle2")
    rest = planner.plan(data)
    ahead = [list(0.3 * (np.array(v["goal"]) - v["start"]) / np.linalg.norm(
        np.array(v["goal"]) - v["start"])) for v in data["vehicles"]]
    moving = planner.plan(_moving(data, ahead))
    assert rest.ok and moving.ok
    assert moving.cost < rest.cost


def test_the_first_jerk_box_binds_on_the_start_acceleration(paper4) -> None:
    """A vehicle accelerating at 3 m/s^2 along x when it must go the other way cannot
    reverse at once: its first acceleration stays within jerk_max * dt of 3 m/s^2."""
    data = copy.deepcopy(paper4)
    data["vehicles"] = data["vehicles"][:1]
    vehicle = data["vehicles"][0]
    vehicle["goal"] = [vehicle["start"][0] - 2.0, vehicle["start"][1], vehicle["start"][2]]
    vehicle["start_acceleration"] = [3.0, 0.0, 0.0]
    plan = planner.plan(data)
    assert plan.ok, plan.problems()
    jerk_dt = data["limits"]["jerk_max"][0] * data["dt"]
    assert plan.accelerations()[0, 0, 0] >= 3.0 - jerk_dt - 1e-6
    at_rest = planner.plan({**data, "vehicles": [{k: vehicle[k] for k in ("id", "start",
                                                                           "goal")}]})
    assert at_rest.accelerations()[0, 0, 0] < 0.0  # without it, it would go straight back


def test_verification_checks_the_start_state(paper4) -> None:
    """A plan flown from rest does not verify against a scenario that starts it moving."""
    plan = planner.plan(paper4)
    moving = planner.Scenario.from_dict(_moving(paper4, [[0.5, 0.0, 0.0]]))
    check = verify(moving, plan.positions(), plan.velocities(), plan.accelerations())
    assert not check.within_bounds
    assert check.boundary_error["start_velocity"] == pytest.approx(0.5)


@pytest.mark.parametrize(("key", "value", "reason"), [
    ("start_velocity", [2.5, 0.0, 0.0], "exceeds the limit 2 m/s"),
    ("start_acceleration", [0.0, -3.5, 0.0], "exceeds the limit 3 m/s^2"),
    ("start_velocity", [0.0, math.nan, 0.0], "finite"),
    ("start_velocity", [1.0, 2.0], "list of 3 numbers"),
    ("start_acceleration", "fast", "list of 3 numbers"),
])
def test_bad_start_states_name_the_field(paper4, key: str, value, reason: str) -> None:
    data = copy.deepcopy(paper4)
    data["vehicles"][2][key] = value
    with pytest.raises(ScenarioError) as info:
        planner.Scenario.from_dict(data)
    assert info.value.field.startswith(f"vehicles[2].{key}")
    assert reason in info.value.reason


def test_a_plan_starting_moving_is_refused_for_flying_and_export(paper4) -> None:
    """A flight or show starts from a hover: `refusal` names a non-zero start_velocity and,
    at zero velocity, a non-zero start_acceleration; a plan at rest passes."""
    still = [0.0, 0.0, 0.0]
    accelerating = planner.plan(_moving(paper4, [still], [still, [0.0, 0.5, 0.0]]))
    assert accelerating.ok, accelerating.problems()
    assert refusal(accelerating) is not None
    assert "vehicles[1].start_acceleration" in (refusal(accelerating) or "")
    moving = planner.plan(_moving(paper4, [[0.0, 0.3, 0.0]]))
    assert "vehicles[0].start_velocity" in (refusal(moving) or "")
    assert refusal(planner.plan(_moving(paper4, [still], [still]))) is None
