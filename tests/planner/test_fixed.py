"""Fixed trajectories (`planner.model.fixed`) and replans (`planner.methods.replan`): planned
vehicles keep
R + margin from known motions over continuous time, and the verifier measures it exactly."""

from __future__ import annotations

import json

import numpy as np
import pytest

from planner import Plan, plan
from planner.errors import ScenarioError
from planner.families.generators import circle_swap
from planner.methods.replan import ReplanError, check_goals, plan_replan, stop_threshold
from planner.model.fixed import DROP_COAST_STEPS, braking_motion, landing_motion
from planner.model.scenario import Scenario
from tests.api.support import SHORT_CROSSING

LIMITS = {"position_min": [0, 0, 0], "position_max": [5, 5, 3], "velocity_max": [2, 2, 2],
          "acceleration_max": [3, 3, 3]}


def _crossing(fixed: list[dict]) -> dict:
    return {"name": "t", "dt": 0.2, "steps": 40, "min_separation": 1.0, "limits": LIMITS,
            "vehicles": [{"id": "a", "start": [0.5, 2.5, 1.5], "goal": [4.5, 2.5, 1.5]},
                         {"id": "b", "start": [4.5, 2.0, 1.0], "goal": [0.5, 2.0, 1.0]}],
            "fixed": fixed}


def test_a_plan_keeps_r_plus_margin_from_a_landing_vehicle_measured_exactly() -> None:
    descent = landing_motion("down", [2.5, 2.5, 2.0], [0.5, 0.0, 0.0], 0.2, 2.0, 0.5, 0.2,
                             margin=0.2)
    result = plan(Scenario.from_dict(_crossing([descent.to_dict()])))
    assert result.ok, result.message
    check = result.verification
    t = np.arange(0.0, 8.0, 0.001)
    planned = result.sample(t).position
    predicted, _, _ = descent.state(t, 0.2)
    dense = float(np.linalg.norm(planned - predicted[None], axis=2).min())
    assert check.fixed_distance_min == pytest.approx(dense, abs=1e-4)
    assert dense >= 1.2 - 1e-3  # R + the full margin, once it has grown
    assert check.closest_fixed["id"] == "down"
    back = Plan.from_dict(json.loads(json.dumps(result.to_dict())))
    assert back.scenario.fixed[0].margin == 0.2
    assert back.verification.closest_fixed == check.closest_fixed


def test_without_the_fixed_vehicle_the_same_crossing_passes_through_its_column() -> None:
    descent = landing_motion("down", [2.5, 2.5, 2.0], [0.0, 0.0, 0.0], 0.2, 2.0, 0.5, 0.2)
    free = plan(Scenario.from_dict(_crossing([])))
    assert "fixed_distance_min" not in free.verification.to_dict()
    t = np.arange(0.0, 8.0, 0.001)
    predicted, _, _ = descent.state(t, 0.2)
    assert np.linalg.norm(free.sample(t).position - predicted[None], axis=2).min() < 1.0


@pytest.mark.parametrize(("fixed", "field"), [
    ([{"id": "a", "positions": [[2.5, 4.5, 1.0]]}], "fixed[0].id"),
    ([{"id": "x", "positions": [[2.5, 4.5, 1.0]]}, {"id": "x", "positions": [[1, 4.5, 1]]}],
     "fixed[1].id"),
    ([{"id": "x", "positions": [[2.5, 4.5, 1.0]] * 42}], "fixed[0].positions"),
    ([{"id": "x", "positions": [[2.5, 4.5, float("nan")]]}], "fixed[0].positions[0][2]"),
    ([{"id": "x", "positions": [[1.0, 2.5, 1.5]]}], "vehicles[0].start"),
    ([{"id": "x", "positions": [[4.5, 2.5, 2.0]], "margin": 0.5}], "vehicles[0].goal"),
    ([{"id": "x", "positions": [[2.5, 4.5, 1.0]], "velocities": []}], "fixed[0].velocities"),
])
def test_bad_fixed_trajectories_are_refused_naming_the_field(fixed, field) -> None:
    with pytest.raises(ScenarioError) as error:
        Scenario.from_dict(_crossing(fixed))
    assert error.value.field == field


def test_braking_motion_stops_within_its_deceleration_and_rests() -> None:
    hold = braking_motion("h", [1.0, 1.0, 1.0], [2.0, 0.0, 0.0], 0.1, 2.0)
    p, v, a = hold.state(np.arange(0.0, 3.0, 0.01), 0.1)
    assert p[-1, 0] == pytest.approx(2.0)  # v^2 / 2d = 1 m on
    assert np.abs(a).max() <= 2.0 + 1e-9
    assert np.all(np.diff(p[:, 0]) >= -1e-12)
    assert np.allclose(v[-50:], 0.0)


def test_a_dropped_vehicle_coasts_on_its_acceleration_then_brakes_and_lands() -> None:
    p0, v0, a0 = np.array([2.0, 2.0, 1.5]), np.array([0.5, -0.2, 0.0]), np.array([1.0, 0.5, 0.2])
    drop = landing_motion("d", p0, v0, 0.2, 2.0, 0.7, 0.3, acceleration=a0, coast_steps=2)
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.39])
    p, v, a = drop.state(t, 0.2)
    assert np.allclose(p, p0 + t[:, None] * v0 + 0.5 * t[:, None] ** 2 * a0)
    assert np.allclose(v, v0 + t[:, None] * a0)
    assert np.allclose(a, a0)
    # then it brakes along its velocity, at most at the deceleration, and goes down
    late = drop.state(np.arange(0.4, 8.0, 0.01), 0.2)
    assert np.linalg.norm(late[2][:, :2], axis=1).max() <= 2.0 + 1e-9
    assert late[0][-1, 2] == pytest.approx(0.3)
    assert np.allclose(late[1][-1], 0.0)
    # without coasting it brakes at once, from where it is
    at_once = landing_motion("d", p0, v0, 0.2, 2.0, 0.7, 0.3)
    assert np.allclose(at_once.state(np.array([0.1]), 0.2)[2][0, :2],
                       -2.0 * v0[:2] / np.linalg.norm(v0))


def _drop_mid_flight(source: dict, t: float, vid: str | None) -> tuple[Plan, object]:
    """Replan the others of `source` at flight time `t` with `vid` (None: the vehicle nearest
    the fleet's centre) dropped to land, its motion as the ground station flies it."""
    base = plan(Scenario.from_dict(source))
    assert base.ok
    ids = list(base.scenario.ids)
    state = base.sample(np.array([t]))
    p, v, a = state.position[:, 0], state.velocity[:, 0], state.acceleration[:, 0]
    d = ids.index(vid) if vid else int(np.argmin(np.linalg.norm(p - p.mean(0), axis=1)))
    keep = [n for n in range(len(ids)) if n != d]
    drop = landing_motion(ids[d], p[d], v[d], base.scenario.dt, 2.0, 0.7, 0.3,
                          acceleration=a[d], coast_steps=DROP_COAST_STEPS)
    replan = plan_replan(base.scenario, [ids[n] for n in keep], p[keep], v[keep], a[keep],
                         base.scenario.goals[keep], fixed=[drop])
    return base, replan


@pytest.mark.parametrize(("source", "t", "vid"), [
    ({**SHORT_CROSSING, "steps": 100}, 10.0, "d"),   # d passes a and c at R
    ({**SHORT_CROSSING, "steps": 100}, 10.5, "d"),
    (circle_swap(16), 15.0, None),                  # everyone at the centre
])
def test_dropping_a_vehicle_at_the_worst_instant_of_a_crossing_gives_a_verified_replan(
        source, t, vid) -> None:
    """Braking at once there leaves a neighbour passing at R no way to clear it on its first
    step; coasting one step on the plan's acceleration keeps what the flying plan proved."""
    _, replan = _drop_mid_flight(source, t, vid)
    check = replan.plan.verification
    assert replan.plan.ok and check.separated and check.flyable
    # R, or a hair less from a state passing at R (from the dropped one: that pair alone)
    assert check.fixed_distance_min >= check.closest_fixed["required"] - 1e-6
    assert check.fixed_distance_min >= 0.99 - 1e-6
    assert replan.separation >= 0.99 - 1e-9
    assert check.min_separation_continuous >= replan.separation - 1e-6


def test_a_replan_from_a_moving_state_avoids_a_dropped_vehicle_and_is_verified() -> None:
    scenario = Scenario.from_dict(_crossing([]))
    base = plan(scenario)
    state = base.sample(np.array([2.0]))
    p, v, a = state.position[:, 0], state.velocity[:, 0], state.acceleration[:, 0]
    dropped = braking_motion("c", [2.5, 4.2, 2.5], [0.0, 0.0, 0.0], 0.2, 2.0, margin=0.1)
    goals = np.array([[4.5, 4.0, 1.0], [0.5, 2.0, 1.0]])
    replan = plan_replan(scenario, ["a", "b"], p, v, a, goals, fixed=[dropped],
                         min_horizon=6.0)
    result = replan.plan
    assert result.ok
    assert np.allclose(result.positions()[:, 0], p, atol=1e-6)
    assert np.allclose(result.velocities()[:, 0], v, atol=1e-6)
    assert np.allclose(result.positions()[:, -1], goals, atol=1e-5)
    assert result.verification.fixed_distance_min >= 1.1 - 1e-4
    assert result.scenario.horizon >= 6.0


def test_a_replan_onto_a_fixed_vehicle_is_refused_and_goals_are_checked() -> None:
    scenario = Scenario.from_dict(_crossing([]))
    resting = braking_motion("c", [4.5, 2.5, 1.5], [0.0, 0.0, 0.0], 0.2, 2.0)
    with pytest.raises(ReplanError):
        plan_replan(scenario, ["a"], [[0.5, 2.5, 1.5]], [[0, 0, 0]], [[0, 0, 0]],
                    [[4.5, 2.5, 1.5]], fixed=[resting])
    with pytest.raises(ScenarioError) as outside:
        check_goals(scenario, {"a": [9.0, 1.0, 1.0]}, {})
    assert outside.value.field == "goals.a"
    with pytest.raises(ScenarioError) as close:
        check_goals(scenario, {"a": [1.0, 1.0, 1.0]}, {"b": [1.5, 1.0, 1.0]})
    assert close.value.field == "goals.a" and "'b'" in close.value.reason
    assert check_goals(scenario, {"a": [1.0, 1.0, 1.0]}, {"b": [3.0, 1.0, 1.0]})["a"][0] == 1.0


def test_a_dropped_vehicle_braking_towards_a_wall_stays_inside_the_workspace() -> None:
    """A plan braking hard (3 m/s^2) towards the wall at x = 10 m: coasting a step and then
    braking at 2 m/s^2 would carry the dropped vehicle 8 cm through the wall, so it brakes at
    once at the boxes' bound instead and stops inside; in open space it coasts first."""
    from planner.model.fixed import dropped_motion

    low, high = np.zeros(3), np.array([10.0, 10.0, 4.0])
    state = ([9.5, 5.0, 2.0], [1.7, 0.0, 0.0], [-3.0, 0.0, 0.0])
    common = {"deceleration": 2.0, "hardest": 3.0, "low": low, "high": high,
              "descent_speed": 0.7, "floor": 0.3}
    for action in ("hold", "land"):
        near = dropped_motion("d", *state, 0.2, action, **common)
        assert near.positions[:, 0].max() <= 10.0
        coasted = braking_motion("d", *state[:2], 0.2, 2.0, acceleration=state[2],
                                 coast_steps=1)
        assert coasted.positions[:, 0].max() > 10.05  # what it would have done
        # far from the wall the same state coasts its step as the plan had it
        open_space = dropped_motion("d", [5.0, 5.0, 2.0], *state[1:], 0.2, action, **common)
        np.testing.assert_allclose(open_space.positions[1], [5.0 + 0.34 - 0.06, 5.0, 2.0])


def test_a_replan_stops_at_a_verified_iterate_within_its_threshold_of_the_optimum() -> None:
    """The replan's looser stop (`stop_threshold`) still gives a verified plan, in fewer
    iterations, and its cost is within that threshold of the same scenario planned to the
    base's tight threshold."""
    base, replan = _drop_mid_flight(circle_swap(16), 12.0, None)
    result = replan.plan
    check = result.verification
    assert result.ok and check.separated and check.clear and check.flyable
    assert check.fixed_distance_min >= replan.separation - 1e-6
    threshold = stop_threshold(base.scenario, len(result.vehicles), result.scenario.steps)
    assert threshold > base.scenario.cost_threshold
    assert result.scenario.cost_threshold == threshold
    assert result.iterations[-1].cost_change < threshold
    tight = plan({**result.scenario.to_dict(), "cost_threshold": base.scenario.cost_threshold})
    assert tight.ok
    assert len(tight.iterations) >= len(result.iterations)
    assert result.iterations[-1].cost <= tight.iterations[-1].cost + threshold
