"""Property tests over random scenarios: the planner either returns a verified plan or says
explicitly that it did not converge or found no solution; it never returns a plan marked
converged that fails its own independent verification."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import planner
from planner import ScenarioError
from planner.verification.verify import verify
from tests.planner.conftest import load_example


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


#: Magnitudes that break naive arithmetic: overflow when squared or divided by, underflow,
#: subnormals, negative zero, integers beyond any float, and what JSON cannot carry.
EXTREMES = [
    1e-300, -1e-300, 1e300, -1e300, 5e-324, -5e-324, 2.2250738585072014e-308,
    1.7976931348623157e308, -0.0, 0.0, 10**400, -(10**400), 2**63, 2**53 + 1, -(2**63),
    math.nan, math.inf, -math.inf, 1e-9, 1e9,
]

#: Every numeric field of a scenario, as a path into the JSON document.
NUMERIC_FIELDS = [
    ("dt",), ("steps",), ("min_separation",), ("separation_margin",), ("cost_threshold",),
    ("max_iterations",),
    *[("separation_scale", i) for i in range(3)],
    *[("limits", key, i) for key in ("position_min", "position_max", "velocity_max",
                                     "acceleration_max", "jerk_max") for i in range(3)],
    ("limits", "thrust_min"), ("limits", "thrust_max"), ("limits", "body_rate_max"),
    *[("vehicles", n, end, i) for n in range(2) for end in ("start", "goal")
      for i in range(3)],
]


def _dotted(path: tuple[Any, ...]) -> str:
    out = ""
    for key in path:
        out += f"[{key}]" if isinstance(key, int) else (f".{key}" if out else key)
    return out


def _base_scenario() -> dict[str, Any]:
    data = load_example("paper-circle2")
    data.update(steps=60, separation_scale=[1.0, 1.0, 1.0], separation_margin=0.0)
    data["limits"]["velocity_max"] = [3.0, 3.0, 3.0]
    for vehicle, (start, goal) in zip(data["vehicles"], [([1.0, 2.5, 1.1], [4.0, 2.5, 1.1]),
                                                         ([4.0, 2.5, 1.9], [1.0, 2.5, 1.9])],
                                      strict=True):
        vehicle.update(start=start, goal=goal)
    return data


def _finite_figures(value: Any) -> bool:
    """Every number in a JSON-like value is finite (None stands for undefined)."""
    if isinstance(value, dict):
        return all(_finite_figures(v) for v in value.values())
    if isinstance(value, list | tuple):
        return all(_finite_figures(v) for v in value)
    if isinstance(value, float):
        return math.isfinite(value)
    return True


def test_the_base_of_the_extreme_magnitudes_plans():
    """The scenario the next test perturbs is valid and flies a crossing (so a perturbation
    that is accepted exercises the separation rows)."""
    plan = planner.plan(_base_scenario())
    assert plan.ok, plan.message
    assert plan.iterations[-1].separation_rows > 0


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(st.sampled_from(NUMERIC_FIELDS),
       st.one_of(st.sampled_from(EXTREMES), st.floats(), st.integers(),
                 st.floats(-12.0, 12.0)))
def test_extreme_magnitudes_are_refused_by_name_or_planned_soundly(path, value):
    """Any magnitude on any numeric field gives either a validation error naming a field and
    saying why, or a plan whose verification is finite and agrees with itself; never an
    overflow, a NaN in the JSON, or a check that passes because it could not be computed."""
    data = _base_scenario()
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    try:
        with np.errstate(all="raise"):  # validation does no arithmetic that can overflow
            scenario = planner.Scenario.from_dict(data)
    except ScenarioError as error:
        assert error.field and error.reason
        assert len(error.reason) < 300  # a huge integer is not spelled out
        # the value's own field, or a check relating it to another (workspace, R, ...)
        assert error.field == _dotted(path) or error.field.startswith(
            ("vehicles[", "limits.position_max", "limits.thrust_max", "separation_margin"))
        return
    # Accepted: the work is bounded by the ranges; plan and check the result.
    assert scenario.steps * len(scenario.vehicles) <= 5000 * 1000
    plan = planner.plan(scenario)
    document = plan.to_dict()
    json.dumps(document, allow_nan=False)
    if plan.verification is None:
        assert plan.status == "infeasible"
        return
    check = verify(scenario, plan.positions(), plan.velocities(), plan.accelerations())
    assert check == plan.verification
    assert _finite_figures(document["verification"])
    if check.separated:
        assert check.min_separation_continuous is not None
        assert check.min_separation_continuous >= (scenario.min_separation
                                                   - check.separation_tolerance)
    assert plan.ok == (plan.status == "converged" and check.verified)


#: The numeric fields of a moving start, the obstacles and the fixed trajectories, as paths
#: into `_base_with_parts` (a box, a cylinder, a prism and a parked fixed vehicle).
PART_FIELDS = [
    *[("vehicles", 0, key, i) for key in ("start_velocity", "start_acceleration")
      for i in range(3)],
    ("obstacle_clearance",),
    *[("obstacles", 0, "box", end, i) for end in ("min", "max") for i in range(3)],
    *[("obstacles", 1, "cylinder", "center", i) for i in range(2)],
    ("obstacles", 1, "cylinder", "radius"),
    *[("obstacles", 1, "cylinder", "z", i) for i in range(2)],
    *[("obstacles", 2, "prism", "polygon", n, i) for n in range(3) for i in range(2)],
    *[("obstacles", 2, "prism", "z", i) for i in range(2)],
    *[("fixed", 0, key, 0, i) for key in ("positions", "velocities") for i in range(3)],
    ("fixed", 0, "margin"),
]


def _base_with_parts() -> dict[str, Any]:
    """`_base_scenario` with a resting start state, three obstacles in the corners and a
    parked fixed vehicle, all out of the crossing's way."""
    data = _base_scenario()
    data["vehicles"][0].update(start_velocity=[0.0, 0.0, 0.0],
                               start_acceleration=[0.0, 0.0, 0.0])
    data["obstacle_clearance"] = 0.3
    data["obstacles"] = [
        {"id": "box", "box": {"min": [0.0, 0.0, 0.0], "max": [0.5, 0.5, 1.0]}},
        {"id": "post", "cylinder": {"center": [4.6, 0.4], "radius": 0.2, "z": [0.0, 2.0]}},
        {"id": "wedge", "prism": {"polygon": [[0.0, 4.4], [0.6, 4.4], [0.0, 5.0]],
                                  "z": [0.0, 1.5]}},
    ]
    data["fixed"] = [{"id": "parked", "positions": [[4.5, 4.5, 2.5]],
                      "velocities": [[0.0, 0.0, 0.0]], "margin": 0.1}]
    return data


def test_the_base_with_parts_plans():
    plan = planner.plan(_base_with_parts())
    assert plan.ok, plan.message
    assert len(plan.scenario.obstacles) == 3 and len(plan.scenario.fixed) == 1


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(st.sampled_from(PART_FIELDS),
       st.one_of(st.sampled_from(EXTREMES), st.floats(), st.integers(),
                 st.floats(-6.0, 6.0)))
def test_extreme_magnitudes_on_start_states_obstacles_and_fixed_vehicles(path, value):
    """The same magnitudes on the numbers of a moving start, an obstacle or a fixed
    trajectory: refused naming the field (or the item it belongs to, or the vehicle it now
    overlaps), or planned with a finite verification that agrees with itself."""
    data = _base_with_parts()
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    try:
        # no overflow or NaN in validation; a tiny vertex may underflow to zero in the
        # polygon's edge lengths, which changes nothing
        with np.errstate(all="raise", under="ignore"):
            scenario = planner.Scenario.from_dict(data)
    except ScenarioError as error:
        assert error.field and error.reason
        assert len(error.reason) < 300
        item = _dotted(path[:2]) if path[0] in ("obstacles", "fixed") else _dotted(path)
        assert error.field.startswith(item) or error.field.startswith("vehicles["), (
            error.field, error.reason)
        return
    plan = planner.plan(scenario)
    json.dumps(plan.to_dict(), allow_nan=False)
    if plan.verification is None:
        assert plan.status == "infeasible"
        return
    check = verify(scenario, plan.positions(), plan.velocities(), plan.accelerations())
    assert check == plan.verification
    assert _finite_figures(plan.to_dict()["verification"])
    assert plan.ok == (plan.status == "converged" and check.verified)


#: Every numeric field of a formation sequence that is not a leg scenario's own setting.
SEQUENCE_FIELDS = [
    ("dt",), ("formations", 1, "duration"), ("formations", 1, "hold"),
    ("formations", 0, "hold"), ("formations", 1, "positions", 0, 0),
    ("formations", 1, "positions", 1, 2), ("separation_scale", 1),
]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SEQUENCE_FIELDS),
       st.one_of(st.sampled_from(EXTREMES), st.floats(), st.integers()))
def test_extreme_magnitudes_in_a_sequence_are_refused_by_name(path, value):
    """The same magnitudes on a sequence's own numbers: parsed into legs or refused naming a
    field, without overflow and without a leg longer than a scenario may be."""
    from planner.methods.sequence import parse_sequence
    from planner.model.scenario import MAX_STEPS

    data = {
        "name": "property", "dt": 0.2, "min_separation": 1.0,
        "separation_scale": [1.0, 1.0, 1.0],
        "limits": {"position_min": [0, 0, 0], "position_max": [6, 6, 3],
                   "velocity_max": [2, 2, 2], "acceleration_max": [3, 3, 3]},
        "vehicles": ["a", "b"],
        "formations": [
            {"positions": [[1, 1, 1], [4, 1, 1]]},
            {"positions": [[1, 4, 1], [4, 4, 1]], "duration": 6.0, "hold": 1.0},
        ],
    }
    node: Any = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    try:
        with np.errstate(all="raise"):
            sequence = parse_sequence(data)
    except ScenarioError as error:
        assert error.field and error.reason and len(error.reason) < 300
        return
    assert all(3 <= leg["steps"] <= MAX_STEPS for leg in sequence.legs)
    assert sum(sequence.holds) <= 10 * MAX_STEPS
