"""A crowded replan (`planner.methods.replan.CROWD_BATCH_ROWS`) is planned in prioritized batches
from the
fleet's moving state, around its dropped vehicles, and as a whole fleet when the batches
fail; a small crowd is planned whole as before."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import planner.methods.replan as replan_module
import planner.methods.stages as stages
from planner.methods.prioritized import NOT_CONVERGED
from planner.methods.replan import CROWD_BATCH_ROWS, Crowd, plan_replan
from planner.model.fixed import landing_motion
from planner.model.scenario import Scenario
from planner.scp.first_qp import solve_first_qp
from planner.scp.loop import thrust_cost
from planner.scp.solvers import make_solver
from tests.planner.batches_support import flying_swap


def _replan(monkeypatch: pytest.MonkeyPatch, rows: int) -> replan_module.Replan:
    """The swap's first five vehicles replanned to their goals with the sixth dropped to land,
    its free moves measured as a crowd of five whose QP starts with `rows` rows."""
    base, p, v, a = flying_swap(2.0)
    monkeypatch.setattr(replan_module, "CROWD_SMALL", 1)  # six vehicles count as a fleet
    monkeypatch.setattr(replan_module, "crowd", lambda *args, **kwargs: Crowd(5, rows))
    dropped = landing_motion("v5", p[5], v[5], base.dt, 2.0, 0.7, 0.3, margin=0.1,
                             acceleration=a[5], coast_steps=1)
    return plan_replan(base, base.ids[:5], p[:5], v[:5], a[:5], base.goals[:5],
                       fixed=[dropped])


def _check(replan: replan_module.Replan, p: np.ndarray, v: np.ndarray) -> None:
    result = replan.plan
    assert result.ok, result.message
    check = result.verification
    assert check is not None and check.separated and check.flyable
    assert check.fixed_distance_min >= replan.separation + 0.1 - 1e-4
    np.testing.assert_allclose(result.positions()[:, 0], p, atol=1e-6)
    np.testing.assert_allclose(result.velocities()[:, 0], v, atol=1e-6)


def test_a_crowded_replan_is_planned_in_batches_from_the_moving_state(
        monkeypatch: pytest.MonkeyPatch) -> None:
    _, p, v, _ = flying_swap(2.0)
    replan = _replan(monkeypatch, CROWD_BATCH_ROWS + 1)
    assert "prioritized batches" in replan.plan.message
    _check(replan, p[:5], v[:5])
    # within the replan's threshold of the optimum: of the separation-free one, a bound
    spec = replan.plan.scenario
    accelerations = np.stack([v.acceleration for v in replan.plan.vehicles])
    free = solve_first_qp(spec, make_solver(None)).accelerations
    assert 0.0 < thrust_cost(accelerations) - thrust_cost(free) < spec.cost_threshold


def test_a_small_crowd_is_replanned_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    _, p, v, _ = flying_swap(2.0)
    replan = _replan(monkeypatch, CROWD_BATCH_ROWS)
    assert "prioritized" not in replan.plan.message
    _check(replan, p[:5], v[:5])


def test_a_crowded_replan_whose_batches_fail_is_planned_whole_in_the_same_attempt(
        monkeypatch: pytest.MonkeyPatch) -> None:
    _, p, v, _ = flying_swap(2.0)
    calls: list[int] = []

    def failing(work: Scenario, *args: Any, **kwargs: Any) -> str:
        calls.append(len(work.vehicles))
        return NOT_CONVERGED

    monkeypatch.setattr(stages, "plan_batches", failing)
    replan = _replan(monkeypatch, CROWD_BATCH_ROWS + 1)
    assert calls == [5] and replan.attempts == 1
    assert "planned as a whole fleet" in replan.plan.message
    _check(replan, p[:5], v[:5])
