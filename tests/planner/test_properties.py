"""Property tests over random scenarios: the planner either returns a verified plan or says
explicitly that it did not converge or found no solution; it never returns a plan marked
converged that fails its own independent verification."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import planner
from planner import ScenarioError
from planner.verify import verify


@st.composite
def scenarios(draw):
    n = draw(st.integers(2, 5))
    size = np.array([draw(st.floats(3.0, 8.0)), draw(st.floats(3.0, 8.0)),
                     draw(st.floats(2.0, 4.0))])
    separation = draw(st.floats(0.4, 1.0))
    scale = draw(st.sampled_from([[1.0, 1.0, 1.0], [1.0, 1.0, 2.0]]))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    points = rng.uniform(0.1, 1.0, size=(2 * n, 3)) * (size - 0.2) + 0.1
    limits = {
        "position_min": [0.0, 0.0, 0.0],
        "position_max": size.tolist(),
        "velocity_max": [draw(st.floats(0.8, 3.0))] * 3,
        "acceleration_max": [draw(st.floats(0.8, 4.0))] * 3,
    }
    if draw(st.booleans()):
        limits["jerk_max"] = [draw(st.floats(1.0, 8.0))] * 3
    return {
        "name": "property",
        "dt": draw(st.sampled_from([0.1, 0.2, 0.25])),
        "steps": draw(st.integers(25, 70)),
        "min_separation": separation,
        "separation_scale": scale,
        "max_iterations": draw(st.integers(1, 12)),
        "limits": limits,
        "vehicles": [
            {"id": f"v{k}", "start": points[k].tolist(), "goal": points[n + k].tolist()}
            for k in range(n)
        ],
    }


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenarios())
def test_plan_is_verified_or_explicitly_not(data):
    try:
        scenario = planner.Scenario.from_dict(data)
    except ScenarioError as error:  # an explicit, named refusal is a valid outcome
        assert error.field and error.reason
        return
    plan = planner.plan(scenario)
    assert plan.status in ("converged", "max_iterations", "infeasible")
    if plan.status == "infeasible":
        assert plan.message and plan.infeasible_groups
        return
    # Check again from scratch: the plan's claims hold on its own trajectories.
    check = verify(scenario, plan.positions(), plan.velocities(), plan.accelerations())
    assert check == plan.verification
    if plan.status == "converged":
        assert plan.ok
        assert plan.iterations[-1].cost_change < scenario.cost_threshold
    # Every iterate after the first QP is separated, converged or not.
    if len(plan.iterations) > 1:
        assert check.separated
