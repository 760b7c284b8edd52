"""A replan's first horizon: the least crowded of a few, measured on its separation-free moves
(`planner.methods.replan.crowd`), and the looser stop that ends its SCP at a verified iterate."""

from __future__ import annotations

import math

import numpy as np
import pytest

import planner.methods.replan as replan_module
from planner import plan
from planner.methods.replan import (
    CROWD_FACTORS,
    Crowd,
    crowd,
    plan_replan,
    replan_horizon,
    stop_threshold,
)
from planner.model.fixed import braking_motion
from planner.model.scenario import Scenario

LIMITS = {"position_min": [0, 0, 0], "position_max": [10, 10, 3], "velocity_max": [2, 2, 2],
          "acceleration_max": [3, 3, 3]}


def _scenario(vehicles: list[tuple[str, list[float], list[float]]]) -> Scenario:
    return Scenario.from_dict({
        "name": "t", "dt": 0.2, "steps": 40, "min_separation": 1.0, "limits": LIMITS,
        "vehicles": [{"id": vid, "start": s, "goal": g} for vid, s, g in vehicles]})


def test_crowd_is_the_largest_group_of_vehicles_whose_free_moves_meet() -> None:
    # a and b meet head on at y = 8; c, d and e all cross (5, 2) at half time
    meeting = _scenario([
        ("a", [1, 8, 1.5], [9, 8, 1.5]), ("b", [9, 8, 1.5], [1, 8, 1.5]),
        ("c", [1, 2, 1.5], [9, 2, 1.5]), ("d", [9, 2, 1.5], [1, 2, 1.5]),
        ("e", [5, 4, 1.5], [5, 0.5, 1.5]),
    ])
    found = crowd(meeting)
    assert found.vehicles == 3
    # c, d and e close in on each other over several steps: a row for each, all theirs
    assert found.rows >= 3
    pair = _scenario([("a", [1, 8, 1.5], [9, 8, 1.5]), ("b", [9, 8, 1.5], [1, 8, 1.5])])
    assert crowd(pair).vehicles == 2 and crowd(pair).rows < found.rows
    apart = _scenario([("a", [1, 8, 1.5], [9, 8, 1.5]), ("b", [1, 2, 1.5], [9, 2, 1.5])])
    assert crowd(apart) == Crowd(0, 0)


def _moving_pair() -> tuple[Scenario, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Two vehicles flying past each other, replanned a second in, to swapped-ish goals."""
    base = _scenario([("a", [1, 5, 1.5], [9, 5.5, 1.5]), ("b", [9, 3, 1.5], [1, 3.5, 1.5])])
    flying = plan(base)
    assert flying.ok
    state = flying.sample(np.array([1.0]))
    p, v, a = state.position[:, 0], state.velocity[:, 0], state.acceleration[:, 0]
    goals = np.array([[8.0, 7.0, 1.5], [2.0, 1.5, 1.5]])
    return base, p, v, a, goals


def test_a_crowded_first_horizon_gives_way_to_the_shortest_least_crowded_one(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Crowds 40, 12, 10 at the three candidates: 12 is within the tolerance of 10, so the
    middle one is taken, and the replan from the moving state there is verified."""
    base, p, v, a, goals = _moving_pair()
    monkeypatch.setattr(replan_module, "CROWD_SMALL", 1)  # a pair counts as a fleet here
    first = replan_horizon(base, p, v, goals)
    steps = [math.ceil(f * first / base.dt) for f in CROWD_FACTORS]
    seen: list[int] = []

    def fake(spec: Scenario, solver: str | None = None) -> Crowd:
        seen.append(spec.steps)
        return Crowd({steps[0]: 40, steps[1]: 12, steps[2]: 10}[spec.steps], 50)

    monkeypatch.setattr(replan_module, "crowd", fake)
    dropped = braking_motion("c", [5.0, 8.5, 2.5], [0.5, 0.0, 0.0], 0.2, 2.0)
    replan = plan_replan(base, ["a", "b"], p, v, a, goals, fixed=[dropped])
    assert seen == steps
    result = replan.plan
    assert result.ok and result.verification.fixed_distance_min >= 1.0 - 1e-6
    assert result.scenario.steps == steps[1]
    assert np.allclose(result.positions()[:, 0], p, atol=1e-6)
    assert np.allclose(result.velocities()[:, 0], v, atol=1e-6)
    assert np.allclose(result.positions()[:, -1], goals, atol=1e-5)


def test_a_small_crowd_keeps_the_first_horizon_without_looking_further(
        monkeypatch: pytest.MonkeyPatch) -> None:
    base, p, v, a, goals = _moving_pair()
    seen: list[int] = []

    def fake(spec: Scenario, solver: str | None = None) -> Crowd:
        seen.append(spec.steps)
        return Crowd(1, 3)

    monkeypatch.setattr(replan_module, "crowd", fake)
    replan = plan_replan(base, ["a", "b"], p, v, a, goals)
    assert replan.plan.ok
    assert seen == []  # a fleet no larger than CROWD_SMALL never looks
    monkeypatch.setattr(replan_module, "CROWD_SMALL", 1)
    replan = plan_replan(base, ["a", "b"], p, v, a, goals)
    assert replan.plan.ok
    assert seen == [replan.plan.scenario.steps]  # a crowd of 1: no further look
    assert replan.plan.scenario.steps == math.ceil(replan_horizon(base, p, v, goals) / base.dt)


def test_the_replan_stop_is_looser_than_the_base_and_scales_with_the_plan() -> None:
    base = _scenario([("a", [1, 8, 1.5], [9, 8, 1.5])])
    assert stop_threshold(base, 100, 200) == pytest.approx(200.0)
    assert stop_threshold(base, 100, 200) == 2 * stop_threshold(base, 50, 200)
    assert stop_threshold(base, 1, 1) == base.cost_threshold  # never tighter than the base
