"""Free goal assignment: optimality, CAPT's collision-free moves, and the plan contract."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import planner
from planner import PlanFormatError, Scenario, ScenarioError
from planner.assignment import CAPT_SPACING, assign_goals, capt_spacing_holds
from planner.first_qp import straight_moves
from planner.generators import grid_to_sphere
from planner.verify import continuous_minimum


def _spread(rng: np.random.Generator, count: int, spacing: float, size: float) -> np.ndarray:
    points: list[np.ndarray] = []
    while len(points) < count:
        c = rng.random(3) * size
        if all(np.linalg.norm(c - p) >= spacing for p in points):
            points.append(c)
    return np.array(points)


@pytest.mark.parametrize("seed", range(6))
def test_assignment_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n = 6
    starts, goals = rng.normal(size=(n, 3)) * 3, rng.normal(size=(n, 3)) * 3
    scale = np.array([1.0, 1.0, 2.0]) if seed % 2 else None
    s = np.ones(3) if scale is None else scale

    def cost(order):
        return float(np.sum(((starts - goals[list(order)]) / s) ** 2))

    best = min(cost(p) for p in itertools.permutations(range(n)))
    order = assign_goals(starts, goals, scale)
    assert sorted(order.tolist()) == list(range(n))
    assert cost(order) == pytest.approx(best, rel=1e-12)


def _scenario(starts, goals, assignment="free", size=12.0):
    return Scenario.from_dict({
        "dt": 0.2, "steps": 60, "min_separation": 1.0, "assignment": assignment,
        "limits": {"position_min": [-1.0] * 3, "position_max": [size + 1.0] * 3},
        "vehicles": [{"id": f"v{n}", "start": s.tolist(), "goal": g.tolist()}
                     for n, (s, g) in enumerate(zip(starts, goals, strict=True))],
    })


@pytest.mark.parametrize("seed", range(4))
def test_capt_moves_are_separated_under_the_spacing_condition(seed):
    rng = np.random.default_rng(100 + seed)
    starts = _spread(rng, 30, CAPT_SPACING, 6.0)
    goals = _spread(rng, 30, CAPT_SPACING, 6.0)
    assert capt_spacing_holds(starts, goals, 1.0)
    free = _scenario(starts, goals).assigned()
    p, v, a = straight_moves(free)
    _, continuous, *_ = continuous_minimum(free, p, v, a)
    assert continuous >= CAPT_SPACING / np.sqrt(2.0) - 1e-9
    # The same points with their given (arbitrary) pairing collide on straight moves,
    # which is what makes the assignment matter.
    fixed = _scenario(starts, goals, "fixed")
    _, crossing, *_ = continuous_minimum(fixed, *straight_moves(fixed))
    assert crossing < 1.0


def test_spacing_condition_detects_close_points():
    close = np.array([[0.0, 0, 0], [1.3, 0, 0]])  # 1.3 < sqrt(2) R
    far = close * 1.1  # 1.43 > sqrt(2) R
    assert not capt_spacing_holds(close, far + 5.0, 1.0)
    assert not capt_spacing_holds(far, close + 5.0, 1.0)
    assert capt_spacing_holds(far, far + 5.0, 1.0)


def test_free_plan_keeps_ids_echoes_given_goals_and_reports_the_assignment():
    data = grid_to_sphere(16, seed=3)
    data["assignment"] = "free"
    plan = planner.plan(data)
    assert plan.ok
    out = plan.to_dict()
    assert [v["id"] for v in out["vehicles"]] == [v["id"] for v in data["vehicles"]]
    assert [v["goal"] for v in out["scenario"]["vehicles"]] == [
        [float(c) for c in v["goal"]] for v in data["vehicles"]]
    assert out["scenario"]["assignment"] == "free"
    order = [out["assignment"][v["id"]] for v in data["vehicles"]]
    assert sorted(order) == list(range(16))
    given = np.array([v["goal"] for v in data["vehicles"]])
    finals = np.array([v["position"][-1] for v in out["vehicles"]])
    np.testing.assert_allclose(finals, given[order], atol=1e-5)
    # The shuffled lattice order is not the optimum: the assignment did something.
    assert order != list(range(16))
    back = planner.Plan.from_dict(out)
    np.testing.assert_array_equal(back.scenario.order, order)
    np.testing.assert_allclose(back.scenario.assigned_goals, finals, atol=1e-5)


def test_fixed_is_the_default_and_reports_the_identity():
    data = grid_to_sphere(9, seed=1)
    plan = planner.plan(data)
    out = plan.to_dict()
    assert out["scenario"]["assignment"] == "fixed"
    assert [out["assignment"][v["id"]] for v in data["vehicles"]] == list(range(9))
    assert plan.ok


def test_bad_assignment_values_name_the_field():
    data = grid_to_sphere(4, seed=None)
    data["assignment"] = "greedy"
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data)
    assert info.value.field == "assignment"
    data["assignment"] = "free"
    out = planner.plan(data).to_dict()
    first = data["vehicles"][0]["id"]
    for bad, field in ((7, f"assignment.{first}"), (True, f"assignment.{first}"),
                       ("x", "assignment")):
        broken = dict(out)
        broken["assignment"] = ({**out["assignment"], first: bad} if field != "assignment"
                                else bad)
        with pytest.raises(PlanFormatError) as info:
            planner.Plan.from_dict(broken)
        assert info.value.field == field
    duplicate = dict(out, assignment={v: 0 for v in out["assignment"]})
    with pytest.raises(PlanFormatError) as info:
        planner.Plan.from_dict(duplicate)
    assert info.value.field in {"assignment", *(f"assignment.{v}" for v in out["assignment"])}


def test_horizon_check_uses_the_assigned_goals():
    # Given pairing: each vehicle crosses the box (too far for the horizon); free: each
    # takes the goal next to it, which is reachable.
    starts = np.array([[0.0, 0, 1], [40.0, 0, 1]])
    goals = np.array([[40.0, 2, 1], [0.0, 2, 1]])
    data = {
        "dt": 0.2, "steps": 20, "min_separation": 1.0,
        "limits": {"position_min": [-1, -1, 0], "position_max": [41, 3, 2],
                   "velocity_max": [2, 2, 2], "acceleration_max": [3, 3, 3]},
        "vehicles": [{"id": f"v{n}", "start": s.tolist(), "goal": g.tolist()}
                     for n, (s, g) in enumerate(zip(starts, goals, strict=True))],
    }
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data)
    assert info.value.field.endswith(".goal")
    scenario = Scenario.from_dict({**data, "assignment": "free"})
    assert scenario.order.tolist() == [1, 0]
