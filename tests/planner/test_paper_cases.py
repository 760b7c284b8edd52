"""The paper's four cases (2, 4, 6, 8 vehicles; circle swaps and random transitions)."""

from __future__ import annotations

import numpy as np
import pytest

import planner
from planner.scp.first_qp import solve_first_qp
from planner.scp.loop import thrust_cost
from planner.scp.solvers import make_solver
from tests.planner.conftest import PAPER_CASES, load_example

BOX_TOLERANCE = 1e-4


@pytest.fixture(scope="module", params=PAPER_CASES)
def case(request):
    scenario = planner.Scenario.from_dict(load_example(request.param))
    return scenario, planner.plan(scenario, method="whole")  # the paper's method


def test_converged_and_verified(case):
    scenario, plan = case
    assert plan.status == "converged", plan.message
    assert plan.ok
    assert plan.iterations[-1].cost_change < scenario.cost_threshold


def test_separated_at_every_step_and_between_steps(case):
    scenario, plan = case
    p = plan.positions()
    scale = scenario.separation_scale
    i, j = np.triu_indices(len(scenario.vehicles), 1)
    at_steps = np.linalg.norm((p[i] - p[j]) / scale, axis=-1)
    assert at_steps.min() >= scenario.min_separation - 1e-6
    # Continuous time, independently of the planner's own check: dense sampling.
    times = np.linspace(0.0, scenario.horizon, scenario.steps * 40 + 1)
    dense = plan.sample(times).position
    between = np.linalg.norm((dense[i] - dense[j]) / scale, axis=-1)
    assert between.min() >= scenario.min_separation - 1e-3
    v = plan.verification
    assert v.min_separation_continuous <= v.min_separation + 1e-12
    assert abs(v.min_separation_continuous - between.min()) < 1e-3


def test_boxes_and_goals(case):
    scenario, plan = case
    lim = scenario.limits
    p, vel, acc = plan.positions(), plan.velocities(), plan.accelerations()
    assert np.all(p >= lim.position_min - BOX_TOLERANCE)
    assert np.all(p <= lim.position_max + BOX_TOLERANCE)
    assert np.all(np.abs(vel) <= lim.velocity_max + BOX_TOLERANCE)
    assert np.all(np.abs(acc) <= lim.acceleration_max + BOX_TOLERANCE)
    jerk = np.stack([v.jerk for v in plan.vehicles])
    assert np.all(np.abs(jerk) <= lim.jerk_max + BOX_TOLERANCE)
    np.testing.assert_allclose(p[:, 0], scenario.starts, atol=BOX_TOLERANCE)
    np.testing.assert_allclose(p[:, -1], scenario.goals, atol=BOX_TOLERANCE)
    np.testing.assert_allclose(vel[:, [0, -1]], 0.0, atol=BOX_TOLERANCE)
    np.testing.assert_allclose(acc[:, -1], 0.0, atol=BOX_TOLERANCE)
    assert max(plan.verification.max_violation.values()) <= BOX_TOLERANCE
    assert max(plan.verification.boundary_error.values()) <= BOX_TOLERANCE


def test_cost_is_the_thrust_cost_and_not_below_the_separation_free_qp(case):
    scenario, plan = case
    free = solve_first_qp(scenario, make_solver())
    free_cost = thrust_cost(free.accelerations)
    assert plan.iterations[0].cost == pytest.approx(free_cost, abs=1e-9)
    assert plan.cost >= free_cost - 1e-6
    a = plan.accelerations()
    direct = np.sum(np.linalg.norm(a + np.array([0.0, 0.0, 9.81]), axis=-1) ** 2)
    assert plan.cost == pytest.approx(direct, rel=1e-12)


def test_trajectories_follow_the_dynamics(case):
    scenario, plan = case
    p, v = planner.integrate(scenario.starts, np.zeros_like(scenario.starts),
                             plan.accelerations(), scenario.dt)
    np.testing.assert_allclose(plan.positions(), p, atol=1e-6)
    np.testing.assert_allclose(plan.velocities(), v, atol=1e-6)


@pytest.mark.parametrize("vehicles", [4, 8])
def test_exactly_symmetric_swaps_are_solved(vehicles):
    """Every vehicle crosses the centre at the same instant (no rotation, one height): all
    pairs coincide in the separation-free QP, the degenerate case of the linearisation."""
    from planner.families.generators import circle_swap

    plan = planner.plan(circle_swap(vehicles, rotation=0.0, height_step=0.0))
    assert plan.status == "converged", plan.message
    assert plan.ok


def test_four_way_head_on_cross_is_solved():
    data = load_example("paper-circle4")
    data["vehicles"] = [
        {"id": "a", "start": [1.0, 3.0, 1.5], "goal": [4.5, 3.0, 1.5]},
        {"id": "b", "start": [4.5, 3.0, 1.5], "goal": [1.0, 3.0, 1.5]},
        {"id": "c", "start": [3.0, 1.0, 1.5], "goal": [3.0, 4.5, 1.5]},
        {"id": "d", "start": [3.0, 4.5, 1.5], "goal": [3.0, 1.0, 1.5]},
    ]
    plan = planner.plan(data)
    assert plan.ok, plan.message
