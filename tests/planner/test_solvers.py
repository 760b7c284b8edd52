"""The QP backends agree, report infeasibility as a status, and plans name the cause."""

from __future__ import annotations

import numpy as np
import pytest

import planner
from planner import SolverError
from planner.scp.qp import SeparationRows, build_group_qp
from planner.scp.separation import PairSteps, directions
from planner.scp.solvers import SOLVERS, make_solver
from tests.planner.conftest import load_example


def _qp_with_separation():
    scenario = planner.Scenario.from_dict(load_example("paper-circle4"))
    members = np.arange(4)
    base = build_group_qp(scenario, members, SeparationRows.empty())
    x = make_solver("piqp").solve(base).x
    p = x.reshape(scenario.steps + 1, 4, 3, 3)[:, :, 0, :].transpose(1, 0, 2)
    i, j = np.triu_indices(4, 1)
    k = np.arange(scenario.steps + 1)
    pairs = PairSteps(np.repeat(i, len(k)), np.repeat(j, len(k)), np.tile(k, len(i)))
    near = np.linalg.norm(p[pairs.i, pairs.k] - p[pairs.j, pairs.k], axis=-1) < 1.5
    pairs = pairs.select(near)
    u = directions(p, scenario.separation_scale, pairs, continuous=False, separation=1.0)
    rows = SeparationRows(pairs.i, pairs.j, pairs.k, np.zeros(len(pairs), np.intp), u)
    return build_group_qp(scenario, members, rows)


def test_backends_agree_on_the_optimum():
    qp = _qp_with_separation()
    results = {name: make_solver(name).solve(qp) for name in SOLVERS}
    assert all(r.status == "solved" for r in results.values())
    reference = results["piqp"]
    for name, result in results.items():
        assert result.objective == pytest.approx(reference.objective, abs=1e-4), name
        np.testing.assert_allclose(result.x, reference.x, atol=1e-3, err_msg=name)
        active = reference.separation_duals > 1e-6
        assert np.all(result.separation_duals[~active] < 1e-3), name


def test_osqp_reuses_its_factorisation_for_the_same_sparsity():
    qp = _qp_with_separation()
    solver = make_solver("osqp")
    first = solver.solve(qp)
    assert solver.setups == 1
    qp.b = qp.b.copy()
    qp.b[-12:] += 0.01  # a slightly different goal: same sparsity, new bounds
    second = solver.solve(qp, warm_start=first.x)
    assert solver.setups == 1  # updated, not set up again
    assert second.status == "solved"
    assert second.iterations < first.iterations


@pytest.mark.parametrize("solver", sorted(SOLVERS))
def test_infeasible_box_is_a_status_naming_vehicle_and_group(solver):
    data = load_example("paper-circle4")
    data["steps"] = 40
    data["limits"]["jerk_max"] = [0.05, 0.05, 0.05]
    plan = planner.plan(data, solver=solver)
    assert plan.status == "infeasible"
    assert plan.infeasible_groups == ("jerk",)
    assert "uav" in plan.message and "jerk" in plan.message
    assert not plan.ok


def test_unknown_solver_is_an_error():
    with pytest.raises(SolverError, match="unknown solver 'cplex'"):
        make_solver("cplex")


@pytest.mark.parametrize("solver", sorted(SOLVERS))
def test_every_backend_plans_a_paper_case(solver):
    plan = planner.plan(load_example("paper-random4"), solver=solver)
    assert plan.ok
    assert plan.solver == solver


def test_a_non_finite_solution_is_a_solver_failure_not_a_plan(monkeypatch):
    """A backend that answers "solved" with NaN in x must not put NaN trajectories in a
    plan: the answer counts as a breakdown and the plan says so, in strict JSON."""
    import json

    from planner.scp.solvers import PiqpSolver, solved

    class Broken(PiqpSolver):
        name = "broken"

        def solve(self, qp, warm_start=None):
            good = super().solve(qp, warm_start)
            x = good.x.copy()
            x[len(x) // 2] = np.nan
            return solved(qp, x, good.iterations, good.seconds, good.separation_duals)

    monkeypatch.setitem(SOLVERS, "broken", Broken)
    plan = planner.plan(load_example("paper-circle2"), solver="broken")
    assert not plan.ok and plan.status == "infeasible"
    assert "failed" in plan.message
    json.dumps(plan.to_dict(), allow_nan=False)
