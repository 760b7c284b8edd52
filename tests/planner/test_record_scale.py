"""The record-scale free-assignment path, at small sizes: the sized horizon, the plan that is
the separation-free optimum, the matchers and the stand-alone optimality certificate, and
the streamed plan JSON."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

import planner
from planner.families.generators import SHOW_STEPS, free_steps, grid_to_sphere
from planner.methods import assignment
from planner.methods.assignment import certify, solve_assignment
from planner.methods.horizon import profile_fits, shortest_steps
from planner.scp.first_qp import unit_profile

BOXES = (np.full(3, 3.0), np.full(3, 3.0), np.full(3, 5.0))  # the show families' v, a, jerk


def _points(data):
    return (np.array([v["start"] for v in data["vehicles"]]),
            np.array([v["goal"] for v in data["vehicles"]]))


@pytest.mark.parametrize("reach", [0.5, 12.0, 60.0, 150.0])
def test_shortest_steps_is_the_first_horizon_whose_profile_fits(reach):
    moves = np.array([[reach, 0.3 * reach, 0.0], [-0.2 * reach, 0.1, 0.4 * reach]])
    k = shortest_steps(moves, 0.2, *BOXES)
    peak = np.abs(moves).max(axis=0)
    assert profile_fits(k, 0.2, peak, *BOXES)
    assert k == 3 or not profile_fits(k - 1, 0.2, peak, *BOXES)
    _, v, _ = unit_profile(k, 0.2)
    assert np.all(peak * np.abs(v).max() <= BOXES[0] + 1e-9)  # the speed limit holds


def test_a_longer_move_needs_a_longer_horizon_and_no_boxes_need_none():
    short = shortest_steps(np.array([[10.0, 0, 0]]), 0.2, *BOXES)
    long = shortest_steps(np.array([[40.0, 0, 0]]), 0.2, *BOXES)
    assert long > short
    assert shortest_steps(np.array([[40.0, 0, 0]]), 0.2, None, None, None) == 3


def test_an_impossible_horizon_is_refused_by_name():
    with pytest.raises(ValueError, match="no horizon"):
        shortest_steps(np.array([[1e9, 0, 0]]), 0.2, *BOXES)


def test_sized_grid_to_sphere_plans_straight_moves_in_closed_form():
    data = {**grid_to_sphere(64, seed=2, steps=None), "assignment": "free"}
    starts, goals = _points(data)
    assert data["steps"] == free_steps(starts, goals)
    assert data["steps"] != SHOW_STEPS  # 64 vehicles need far less than 30 s
    plan = planner.plan(data)
    assert plan.ok
    assert [r.qp_solves for r in plan.iterations] == [0]  # closed form, no loop
    # one step fewer and some assigned move's profile breaks a box
    order = solve_assignment(starts, goals).order
    peak = np.abs(goals[order] - starts).max(axis=0)
    assert not profile_fits(data["steps"] - 1, data["dt"], peak, *BOXES)


def test_grid_to_sphere_keeps_its_default_horizon():
    assert grid_to_sphere(16, seed=0)["steps"] == SHOW_STEPS


def test_straight_moves_that_collide_go_through_the_loop():
    # CAPT's spacing fails (1.05 m < sqrt(2) R): the straight moves meet at 0.74 m, so the
    # separation-free optimum is not the plan and the SCP loop separates it.
    h = 3.0
    data = {"dt": 0.2, "steps": 40, "min_separation": 1.0, "assignment": "free",
            "limits": {"position_min": [-5, -5, 0], "position_max": [5, 5, 6],
                       "velocity_max": [3] * 3, "acceleration_max": [3] * 3},
            "vehicles": [{"id": "a", "start": [-0.525, 0, h], "goal": [0, -0.525, h]},
                         {"id": "b", "start": [0.525, 0, h], "goal": [0, 0.525, h]}]}
    plan = planner.plan(data)
    assert plan.ok
    assert len(plan.iterations) > 1
    assert plan.verification.min_separation_continuous >= 1.0 - 1e-4


@pytest.mark.parametrize("use", ["scipy", "lapmod"])
@pytest.mark.parametrize("seed", range(3))
def test_both_matchers_give_the_dense_optimum(monkeypatch, use, seed):
    if use == "lapmod":
        pytest.importorskip("lap")
    monkeypatch.setattr(assignment, "matcher", lambda: use)
    rng = np.random.default_rng(seed)
    n = 300
    starts, goals = rng.random((n, 3)) * 20, rng.random((n, 3)) * 20 + 3
    sparse = solve_assignment(starts, goals, dense_below=2)
    cost = ((starts[:, None, :] - goals[None, :, :]) ** 2).sum(axis=2)
    rows, cols = linear_sum_assignment(cost)
    assert sparse.method == "sparse" and sparse.proven
    assert sparse.cost == pytest.approx(cost[rows, cols].sum(), rel=1e-9)


@pytest.mark.parametrize("seed", range(8))
def test_the_certificate_accepts_the_optimum_and_rejects_a_worse_order(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 90))
    starts = rng.normal(size=(n, 3)) * rng.uniform(1, 5)
    goals = rng.normal(size=(n, 3)) * rng.uniform(1, 5) + rng.normal(size=3)
    cost = ((starts[:, None, :] - goals[None, :, :]) ** 2).sum(axis=2)
    rows, cols = linear_sum_assignment(cost)
    best = np.empty(n, dtype=np.intp)
    best[rows] = cols
    assert certify(starts, goals, best)
    worse = best.copy()
    worse[[0, 1]] = worse[[1, 0]]
    if cost[np.arange(n), worse].sum() > cost[np.arange(n), best].sum() * (1 + 1e-9):
        assert not certify(starts, goals, worse)
    shuffled = rng.permutation(n)
    if cost[np.arange(n), shuffled].sum() > cost[np.arange(n), best].sum() * (1 + 1e-9):
        assert not certify(starts, goals, shuffled)


def test_the_certificate_refuses_what_is_not_a_permutation():
    points = np.arange(9.0).reshape(3, 3)
    with pytest.raises(ValueError, match="permutation"):
        certify(points, points, np.array([0, 0, 1]))


def test_the_streamed_plan_json_is_the_plan_document():
    plan = planner.plan({**grid_to_sphere(20, seed=3, steps=None), "assignment": "free"})
    stream = io.StringIO()
    plan.write_json(stream)
    written = json.loads(stream.getvalue())
    assert written == json.loads(json.dumps(plan.to_dict()))
    back = planner.Plan.from_dict(written)
    assert np.array_equal(back.positions(), plan.positions())
