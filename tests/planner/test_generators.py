"""Scenario generators, including the dmpc2019 benchmark distribution."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import planner
from planner.families.generators import (
    circle_swap,
    dmpc2019_points,
    dmpc2019_scenario,
    grid_to_sphere,
    random_dense,
    random_transitions,
    sideways,
)

PUBLISHED = Path(__file__).resolve().parents[2] / "bench" / "dmpc2019-published.json"


def test_dmpc2019_generator_reproduces_the_authors_stored_trial():
    stored = json.loads(PUBLISHED.read_text())["stored_last_trial"]
    stream = np.random.RandomState(5489)  # MATLAB's default Mersenne Twister
    stream.random_sample(1_114_470)  # the draws made before that trial (see the README)
    starts = dmpc2019_points(stream.random_sample, stored["N"])
    goals = dmpc2019_points(stream.random_sample, stored["N"])
    np.testing.assert_array_equal(starts, stored["start"])
    np.testing.assert_array_equal(goals, stored["goal"])


def test_dmpc2019_scenarios_follow_the_benchmark_parameters():
    data = dmpc2019_scenario(12, seed=1, trial=4)
    scenario = planner.Scenario.from_dict(data)
    assert scenario.steps == 50 and scenario.dt == 0.2
    assert scenario.limits.velocity_max is None and scenario.limits.jerk_max is None
    np.testing.assert_array_equal(scenario.limits.acceleration_max, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(scenario.separation_scale, [1.0, 1.0, 2.0])
    assert dmpc2019_scenario(12, seed=1, trial=4) == data  # deterministic
    assert dmpc2019_scenario(12, seed=1, trial=5) != data


def test_other_generators_give_valid_scenarios():
    for data in (circle_swap(10), random_transitions(20, seed=2)):
        scenario = planner.Scenario.from_dict(data)
        assert len(scenario.vehicles) == len(data["vehicles"])


def _min_distance(points: np.ndarray) -> float:
    d = np.linalg.norm(points[:, None] - points[None], axis=2)
    d[np.diag_indices(len(points))] = np.inf
    return float(d.min())


@pytest.mark.parametrize("n", [25, 100])
def test_grid_to_sphere_geometry_and_limits(n):
    data = grid_to_sphere(n, seed=4)
    scenario = planner.Scenario.from_dict(data)
    starts, goals = scenario.starts, scenario.goals
    assert np.all(starts[:, 1] == 0.0)  # a vertical grid in the x-z plane
    assert _min_distance(starts) == pytest.approx(2.0)
    assert _min_distance(goals) == pytest.approx(2.1, abs=1e-5)
    centre = goals.mean(axis=0)
    radius = np.linalg.norm(goals - centre, axis=1)
    assert np.ptp(radius) < 0.05 * radius.mean()  # a shell
    assert scenario.horizon == pytest.approx(30.0) and scenario.min_separation == 1.0
    np.testing.assert_array_equal(scenario.limits.velocity_max, [3, 3, 3])
    np.testing.assert_array_equal(scenario.limits.acceleration_max, [3, 3, 3])
    np.testing.assert_array_equal(scenario.limits.jerk_max, [5, 5, 5])
    # Seeds shuffle which point each vehicle gets, not the shell.
    other = planner.Scenario.from_dict(grid_to_sphere(n, seed=5)).goals
    assert not np.array_equal(other, goals)
    np.testing.assert_allclose(np.sort(other, axis=0), np.sort(goals, axis=0))


def test_random_dense_density_and_moves():
    data = random_dense(64, seed=3)
    scenario = planner.Scenario.from_dict(data)
    volume = np.prod(scenario.limits.position_max - scenario.limits.position_min)
    assert volume / 64 == pytest.approx(100.0)  # random128's 40 x 40 x 8 m / 128
    assert np.linalg.norm(scenario.goals - scenario.starts, axis=1).max() <= 40.0
    assert _min_distance(scenario.starts) > 1.2 and _min_distance(scenario.goals) > 1.2
    assert scenario.horizon == pytest.approx(30.0)
    assert random_dense(64, seed=4) != data


@pytest.mark.parametrize("seed", [0, 1])
def test_small_grid_to_sphere_transitions_plan_verified(seed):
    plan = planner.plan(grid_to_sphere(16, seed=seed), method="whole")
    assert plan.ok, plan.message
    assert plan.verification.min_separation_continuous >= 1.0 - 1e-4
    # Shuffled goals make paths cross: the separation rows were needed.
    assert max(r.separation_rows for r in plan.iterations) > 0


@pytest.mark.parametrize(("n", "spacing", "offset"), [(25, 2.0, 4.0), (64, 2.5, 8.0)])
def test_sideways_puts_the_shell_beside_the_grid(n, spacing, offset):
    scenario = planner.Scenario.from_dict(sideways(n, spacing=spacing, offset=offset))
    starts, goals = scenario.starts, scenario.goals
    assert np.all(starts[:, 1] == 0.0)  # the same vertical grid as grid -> sphere
    assert _min_distance(starts) == pytest.approx(spacing)
    assert _min_distance(goals) == pytest.approx(1.05 * spacing, abs=1e-5)
    centre = goals.mean(axis=0)
    radius = np.linalg.norm(goals - centre, axis=1)
    assert np.ptp(radius) < 0.05 * radius.mean()  # a shell
    # beside the grid: its nearest point `offset` beyond the last column, lowest 2 m up
    assert goals[:, 0].min() - starts[:, 0].max() == pytest.approx(offset, abs=0.2)
    assert goals[:, 2].min() == pytest.approx(2.0, abs=0.2)
    assert np.all(scenario.starts >= scenario.limits.position_min)
    assert np.all(scenario.goals <= scenario.limits.position_max)
    # lattice order: the grid bottom to top, the shell top to bottom
    assert np.all(np.diff(starts[:, 2]) >= 0) and np.all(np.diff(goals[:, 2]) <= 1e-9)
    assert scenario.horizon == pytest.approx(30.0) and scenario.min_separation == 1.0


def test_sideways_seeds_turn_the_shell_not_its_order():
    plain = planner.Scenario.from_dict(sideways(36)).goals
    turned = planner.Scenario.from_dict(sideways(36, seed=3)).goals
    assert not np.allclose(plain, turned)
    # the same shell turned rigidly: its points the same distances apart
    d_plain = np.linalg.norm(plain[:, None] - plain[None], axis=2)
    d_turned = np.linalg.norm(turned[:, None] - turned[None], axis=2)
    np.testing.assert_allclose(d_plain, d_turned, atol=1e-5)


def test_a_small_sideways_transition_plans_verified():
    plan = planner.plan(sideways(16))
    assert plan.ok, plan.message
    assert plan.verification.min_separation_continuous >= 1.0 - 1e-4
    # lattice order turns the formation upside down on the way: the rows were needed
    assert max(r.separation_rows for r in plan.iterations) > 0
