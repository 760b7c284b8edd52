"""Group QPs through their dual (planner.scp.dual): the same optimum and multipliers as the primal
staged QP, infeasibility reported, and whole plans that stay verified with the same cost."""

from __future__ import annotations

import numpy as np
import pytest

import planner
from planner.families.generators import grid_to_sphere, random_dense
from planner.model.scenario import Scenario
from planner.scp.boxes import near_boxes
from planner.scp.dual import solve_group_dual
from planner.scp.first_qp import straight_moves
from planner.scp.functionals import functionals
from planner.scp.loop import ScpOptions
from planner.scp.qp import BoxMask, SeparationRows, StageLayout, build_group_qp
from planner.scp.separation import PairSteps, all_pairs, close_rows, directions
from planner.scp.solvers import INFEASIBLE, SOLVED, make_solver
from tests.planner.conftest import load_example


def _rows(scenario: Scenario, lin: np.ndarray, pairs: PairSteps) -> SeparationRows:
    """The interval rows (three kinds) of `pairs`, linearised about `lin`."""
    u = directions(lin, scenario.separation_scale, pairs, True, scenario.min_separation)
    coef = u / scenario.separation_scale
    count = len(pairs)
    return SeparationRows(
        i=np.tile(pairs.i, 3), j=np.tile(pairs.j, 3), k=np.tile(pairs.k, 3),
        kind=np.repeat(np.arange(3), count), coef=np.tile(coef, (3, 1)),
    )


def _primal(scenario, members, rows, boxes):
    qp = build_group_qp(scenario, members, rows, boxes)
    result = make_solver("piqp").solve(qp)
    assert result.status == SOLVED
    return StageLayout(scenario.steps, len(members)).unpack(result.x), result


def test_compliance_is_symmetric_and_moves_nothing_fixed():
    fn = functionals(40, 0.2)
    W = fn.compliance
    assert np.allclose(W, W.T, atol=1e-12)
    assert np.linalg.eigvalsh(W).min() > -1e-9  # positive semidefinite
    # The start (p_0, v_0) and the goal (p_K, v_K, a_{K-1}) are fixed: no force moves them.
    for f in (fn.position(0), fn.velocity(0), fn.position(40), fn.velocity(40),
              fn.acceleration(39)):
        assert np.abs(W[f]).max() < 1e-9


def test_dual_group_equals_primal():
    # random16 linearised about the straight moves: rows at every interval where a pair is
    # within 1.2 R, and boxes of every kind (velocity, acceleration, jerk, wall rows) over
    # part of the move.
    scenario = Scenario.from_dict(load_example("random16"))
    lin = straight_moves(scenario)
    pairs, _ = close_rows(lin[0], scenario.separation_scale, 1.2 * scenario.min_separation,
                          True)
    rows = _rows(scenario, lin[0], pairs)
    members = np.arange(len(scenario.vehicles))
    n, steps = len(members), scenario.steps
    boxes = BoxMask(np.zeros((n, steps + 1, 3, 3), dtype=bool),
                    np.zeros((n, steps, 3), dtype=bool), np.zeros((n, steps, 3), dtype=bool))
    boxes.bounds[:, 60:80, 1, :2] = True  # velocity, x and y
    boxes.bounds[:, 70:80, 2, :] = True  # acceleration
    boxes.jerk[:, :10, :] = True
    boxes.wall[:, 60:90, 2] = True
    (p, v, a), primal = _primal(scenario, members, rows, boxes)
    dual = solve_group_dual(scenario, members, rows, boxes)
    assert dual is not None and dual.status == SOLVED
    dp, dv, da = dual.solution
    assert np.abs(dp - p).max() < 1e-5
    assert np.abs(dv - v).max() < 1e-5
    assert np.abs(da - a).max() < 1e-5
    # The same active rows (positive multipliers), at the same values.
    active = primal.separation_duals > 1e-6
    assert active.any()
    assert np.array_equal(dual.separation_duals > 1e-6, active)
    assert np.allclose(dual.separation_duals[active], primal.separation_duals[active],
                       rtol=1e-3, atol=1e-6)


def _every_row(scenario: Scenario) -> SeparationRows:
    """The interval rows of every pair at every interval, about the straight moves."""
    lin = straight_moves(scenario)[0]
    n, steps = len(scenario.vehicles), scenario.steps
    i, j = all_pairs(n)
    pairs = PairSteps(np.repeat(i, steps), np.repeat(j, steps),
                      np.tile(np.arange(steps), len(i)))
    return _rows(scenario, lin, pairs)


def test_dual_declines_a_group_whose_matrix_would_be_huge(monkeypatch):
    # Every pair at every interval and every box of every vehicle: thousands of rows per
    # vehicle, all coupled to each other. Its working sets fit the real MAX_PAIRS (they
    # hold about one row per pair and vehicle); lowered below the first set's block, the
    # dual declines and the caller solves the primal instead.
    import planner.scp.dual

    monkeypatch.setattr(planner.scp.dual, "MAX_PAIRS", 100)
    scenario = Scenario.from_dict(load_example("paper-circle8"))
    n, steps = len(scenario.vehicles), scenario.steps
    rows = _every_row(scenario)
    assert solve_group_dual(scenario, np.arange(n), rows, BoxMask.full(n, steps)) is None


def test_a_group_whose_whole_matrix_is_huge_solves_over_its_working_sets():
    # The same group at the real MAX_PAIRS: its whole Q exceeds it, its working sets do
    # not, and the dual's optimum is the primal's.
    from planner.scp.dual import MAX_PAIRS

    data = load_example("paper-circle8")
    data["dt"], data["steps"] = data["dt"] * data["steps"] / 40, 40  # a primal of seconds
    scenario = Scenario.from_dict(data)
    n, steps = len(scenario.vehicles), scenario.steps
    rows = _every_row(scenario)
    boxes = BoxMask.full(n, steps)
    entries = np.bincount(np.concatenate([rows.i, rows.j]), minlength=n).astype(np.int64)
    assert np.sum(entries ** 2) > MAX_PAIRS  # the separation rows alone
    dual = solve_group_dual(scenario, np.arange(n), rows, boxes)
    assert dual is not None and dual.status == SOLVED
    (p, _, a), _ = _primal(scenario, np.arange(n), rows, boxes)
    assert np.abs(dual.solution[0] - p).max() < 1e-5
    assert np.abs(dual.solution[2] - a).max() < 1e-5


def test_one_sided_rows_hold_the_other_vehicle_fixed():
    # Vehicle 1 flies its straight move while vehicle 0 must keep R from it: rows with the
    # other vehicle as a constant (j = -1, offset), as the block sweeps build them.
    scenario = Scenario.from_dict(load_example("paper-circle4"))
    lin = straight_moves(scenario)
    steps = scenario.steps
    pairs = PairSteps(np.zeros(steps, dtype=np.intp), np.ones(steps, dtype=np.intp),
                      np.arange(steps))
    two = _rows(scenario, lin[0], pairs)
    stage = np.where(two.kind == 2, two.k + 1, two.k)
    point = lin[0][1, stage] + np.where((two.kind == 1)[:, None],
                                        0.5 * scenario.dt * lin[1][1, two.k], 0.0)
    rows = SeparationRows(i=np.zeros(len(two), dtype=np.intp), j=np.full(len(two), -1),
                          k=two.k, kind=two.kind, coef=two.coef,
                          offset=np.einsum("rc,rc->r", two.coef, point))
    members = np.array([0])
    boxes = near_boxes(scenario, *(x[:1] for x in lin))
    (p, _, _), _ = _primal(scenario, members, rows, boxes)
    dual = solve_group_dual(scenario, members, rows, boxes)
    assert dual is not None and dual.status == SOLVED
    assert np.abs(dual.solution[0] - p).max() < 1e-5
    # Vehicle 0 went around vehicle 1's fixed path.
    gap = np.linalg.norm(dual.solution[0][0] - lin[0][1], axis=-1)
    assert gap.min() >= scenario.min_separation - 1e-5


def test_a_row_on_the_fixed_start_is_reported_infeasible():
    scenario = Scenario.from_dict(load_example("paper-circle2"))
    start_gap = scenario.starts[0] - scenario.starts[1]
    # A direction across the start offset: the fixed starts cannot give R along it.
    across = np.cross(start_gap, [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    rows = SeparationRows(i=np.array([0]), j=np.array([1]), k=np.array([0]),
                          kind=np.array([0]), coef=across[None, :])
    steps = scenario.steps
    no_boxes = BoxMask(np.zeros((2, steps + 1, 3, 3), dtype=bool),
                       np.zeros((2, steps, 3), dtype=bool), np.zeros((2, steps, 3), dtype=bool))
    outcome = solve_group_dual(scenario, np.arange(2), rows, no_boxes)
    assert outcome is not None and outcome.status == INFEASIBLE
    assert outcome.solution is None


@pytest.mark.parametrize("data", [
    load_example("random64"),
    grid_to_sphere(25, seed=1),  # a crowd crossing the centre: some groups stay primal
    random_dense(48, seed=3),
], ids=["random64", "grid-sphere25", "dense48"])
def test_plans_with_dual_groups_are_verified_at_the_primal_cost(data):
    dual = planner.plan(data, method="whole")
    primal = planner.plan(data, options=ScpOptions(dual=False), method="whole")
    assert dual.ok, dual.message
    assert primal.ok, primal.message
    assert dual.verification.min_separation_continuous >= 1.0 - 1e-4
    assert dual.cost == pytest.approx(primal.cost, rel=1e-6)
    assert np.abs(dual.positions() - primal.positions()).max() < 1e-3


def test_other_backends_keep_the_primal_and_agree():
    data = load_example("paper-random8")
    assert (planner.plan(data, solver="clarabel", method="whole").cost
            == pytest.approx(planner.plan(data, method="whole").cost, rel=1e-6))


def test_a_dual_that_does_not_solve_falls_back_to_the_primal(monkeypatch):
    import planner.scp.group_solver as group_solver
    from planner.scp.dual import DualOutcome

    calls = []

    def broken(*args, **kwargs):
        calls.append(1)
        return DualOutcome("failed", None, None, 0)

    data = load_example("random64")
    reference = planner.plan(data, method="whole")
    monkeypatch.setattr(group_solver, "solve_group_dual", broken)
    fallback = planner.plan(data, method="whole")
    assert calls
    assert fallback.ok, fallback.message
    assert fallback.cost == pytest.approx(reference.cost, rel=1e-6)


def test_a_long_horizon_keeps_the_primal(monkeypatch):
    """Above DUAL_MAX_STEPS the dual's dense functional matrix (5K x 5K) is never built: a
    2-vehicle crossing over 5,000 steps would need 5 GB for it."""
    import planner.scp.group_solver as group_solver
    import planner.scp.loop as scp
    from planner.scp.dual import DualOutcome

    calls: list[int] = []

    def counting(*args, **kwargs):
        calls.append(1)
        return DualOutcome("failed", None, None, 0)

    monkeypatch.setattr(group_solver, "solve_group_dual", counting)
    data = load_example("paper-circle2")
    data["steps"] = scp.DUAL_MAX_STEPS
    assert planner.plan(data, method="whole").ok and calls  # at the bound: tried
    calls.clear()
    data["steps"] = scp.DUAL_MAX_STEPS + 1
    plan = planner.plan(data, method="whole")
    assert plan.ok, plan.message
    assert plan.iterations[-1].separation_rows > 0  # the crossing did meet separation rows
    assert calls == []


def _random16_rows(within: float):
    """random16's interval rows where pairs come within `within` of each other at the
    straight moves, and every box over part of the move (velocity, acceleration, jerk, wall)."""
    scenario = Scenario.from_dict(load_example("random16"))
    lin = straight_moves(scenario)
    pairs, _ = close_rows(lin[0], scenario.separation_scale,
                          within * scenario.min_separation, True)
    n, steps = len(scenario.vehicles), scenario.steps
    boxes = BoxMask(np.zeros((n, steps + 1, 3, 3), dtype=bool),
                    np.zeros((n, steps, 3), dtype=bool), np.zeros((n, steps, 3), dtype=bool))
    boxes.bounds[:, 60:80, 1, :2] = True
    boxes.bounds[:, 70:80, 2, :] = True
    boxes.jerk[:, :10, :] = True
    boxes.wall[:, 60:90, 2] = True
    return scenario, lin, pairs, boxes


def test_blocks_and_slacks_of_the_dual_equal_the_matrix_built_whole():
    # The working set's blocks of Q = C M C' and every row's slack Q l + c read through the
    # forces equal Q built from C and M explicitly.
    from planner.scp.dual import GroupDual

    scenario, lin, pairs, _ = _random16_rows(1.2)
    rows = _rows(scenario, lin[0], pairs)
    fn = functionals(scenario.steps, scenario.dt)
    n, count = len(scenario.vehicles), fn.compliance.shape[0]
    e_row = np.concatenate([np.arange(len(rows))] * 2)
    e_veh = np.concatenate([rows.i, rows.j])
    f_sep = np.where(rows.kind == 0, fn.position(rows.k),
                     np.where(rows.kind == 1, fn.middle(rows.k), fn.position(rows.k + 1)))
    e_func = np.concatenate([f_sep, f_sep])
    e_coef = np.concatenate([rows.coef, -rows.coef])
    rng = np.random.default_rng(0)
    c = rng.normal(size=len(rows))
    dual = GroupDual(fn, n, e_row, e_veh, e_func, e_coef, c)
    # Q = sum over vehicles and axes of C_va W C_va', C_va: the rows' coefficients on that
    # vehicle's and axis' functionals.
    Q = np.zeros((len(rows), len(rows)))
    for vehicle in range(n):
        for axis in range(3):
            C = np.zeros((len(rows), count))
            mine = e_veh == vehicle
            np.add.at(C, (e_row[mine], e_func[mine]), e_coef[mine, axis])
            Q += C @ fn.compliance @ C.T
    some = np.sort(rng.choice(len(rows), size=len(rows) // 3, replace=False))
    for subset in (some, np.arange(len(rows))):
        block = dual.block(subset).toarray()
        np.testing.assert_allclose(block, np.triu(Q[np.ix_(subset, subset)]), atol=1e-12)
    lam = np.where(rng.random(len(rows)) < 0.2, rng.random(len(rows)), 0.0)
    np.testing.assert_allclose(dual.gradient(dual.moves(lam)), Q @ lam + c, atol=1e-10)


def test_a_warm_started_dual_equals_the_primal_with_rows_added():
    # The SCP loop's pattern: a group solved, a few violated rows added, solved again from
    # the rows the first solve found active (ActiveRows); the same optimum and multipliers
    # as the primal QP of the larger problem.
    from planner.scp.dual import ActiveRows

    scenario, lin, pairs, boxes = _random16_rows(1.2)
    members = np.arange(len(scenario.vehicles))
    keys = pairs.keys(len(members), scenario.steps + 1)
    order = np.argsort(keys)
    pairs, keys = pairs.select(order), keys[order]
    first = np.arange(len(keys)) % 4 != 0  # three quarters of the rows, then all of them

    def ids(k):
        return (3 * k[None, :] + np.arange(3)[:, None]).reshape(-1)

    memory = ActiveRows()
    before = solve_group_dual(scenario, members, _rows(scenario, lin[0], pairs.select(first)),
                              boxes, row_ids=ids(keys[first]), memory=memory)
    assert before is not None and before.status == SOLVED
    assert memory.separation.size > 0
    rows = _rows(scenario, lin[0], pairs)
    (p, _, a), primal = _primal(scenario, members, rows, boxes)
    warm = solve_group_dual(scenario, members, rows, boxes, row_ids=ids(keys), memory=memory)
    cold = solve_group_dual(scenario, members, rows, boxes)
    for outcome in (warm, cold):
        assert outcome is not None and outcome.status == SOLVED
        assert np.abs(outcome.solution[0] - p).max() < 1e-5
        assert np.abs(outcome.solution[2] - a).max() < 1e-5
        # The same multipliers (degenerate rows may share a few 1e-6 differently).
        np.testing.assert_allclose(outcome.separation_duals, primal.separation_duals,
                                   atol=1e-5)
        clear = 1e-3 * primal.separation_duals.max()
        assert np.array_equal(outcome.separation_duals > clear,
                              primal.separation_duals > clear)
    # The memory now names exactly the rows active in the last solve.
    assert np.array_equal(memory.separation, np.sort(ids(keys)[warm.separation_duals > 1e-7]))
