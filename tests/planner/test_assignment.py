"""Free goal assignment: optimality, CAPT's collision-free moves, and the plan contract."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import planner
from planner import PlanFormatError, Scenario, ScenarioError
from planner.families.generators import grid_to_sphere, sphere_shell, vertical_grid
from planner.methods import assignment
from planner.methods.assignment import (
    CAPT_SPACING,
    assign_goals,
    capt_spacing_holds,
    solve_assignment,
)
from planner.scp.first_qp import straight_moves
from planner.verification.verify import continuous_minimum


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


# --------------------------------------------------------------------------- the sparse path

def _dense_optimum(starts, goals, scale=None):
    return solve_assignment(starts, goals, scale, dense_below=10**9)


def _sparse(starts, goals, scale=None, **options):
    return solve_assignment(starts, goals, scale, dense_below=2, **options)


def _clusters(rng, big=200, small=100):
    """`big` starts and `small` goals around the origin, `small` starts and `big` goals 60 m
    away: the nearest-k graph matches the crowded starts only to the few goals beside them."""
    near = rng.normal(size=(big + small, 3))
    far = rng.normal(size=(big + small, 3)) + np.array([60.0, 0.0, 0.0])
    starts = np.concatenate([near[:big], far[:small]])
    goals = np.concatenate([near[big:], far[small:]])
    return starts, goals


def _structured(name, n):
    if name == "grid-sphere":
        data = grid_to_sphere(n, seed=1)
        return (np.array([v["start"] for v in data["vehicles"]]),
                np.array([v["goal"] for v in data["vehicles"]]))
    shell = sphere_shell(n)
    radius = float(np.linalg.norm(shell[0]))
    grid = vertical_grid(n)
    return grid, shell + np.array([grid[:, 0].max() + radius + 4.0, 0.0, radius + 2.0])


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("scale", [None, (1.0, 1.0, 2.0)])
def test_sparse_matches_dense_on_random_points(seed, scale):
    rng = np.random.default_rng(seed)
    starts, goals = rng.random((400, 3)) * 30, rng.random((400, 3)) * 30
    sparse, dense = _sparse(starts, goals, scale), _dense_optimum(starts, goals, scale)
    assert sparse.method == "sparse" and dense.method == "dense"
    assert sorted(sparse.order.tolist()) == list(range(400))
    assert sparse.proven
    assert sparse.cost == pytest.approx(dense.cost, rel=1e-9)
    assert sparse.lower_bound <= dense.cost * (1 + 1e-9)
    assert sparse.gap <= 1e-6 * dense.cost


@pytest.mark.parametrize("name", ["grid-sphere", "sideways"])
def test_sparse_matches_dense_on_show_formations(name):
    starts, goals = _structured(name, 300)
    sparse, dense = _sparse(starts, goals), _dense_optimum(starts, goals)
    assert sparse.proven
    assert sparse.cost == pytest.approx(dense.cost, rel=1e-9)
    # CAPT's property holds for the sparse optimum too: r0'r1 >= 0 for every pair
    r0 = starts[:, None, :] - starts[None, :, :]
    moved = goals[sparse.order]
    r1 = moved[:, None, :] - moved[None, :, :]
    assert np.einsum("ijk,ijk->ij", r0, r1).min() >= -1e-6


def test_a_graph_without_a_full_matching_still_gives_the_optimum():
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching
    from scipy.spatial import cKDTree

    starts, goals = _clusters(np.random.default_rng(5))
    n, k = len(starts), 4
    _, near_goals = cKDTree(goals).query(starts, k)
    _, near_starts = cKDTree(starts).query(goals, k)
    rows = np.concatenate([np.repeat(np.arange(n), k), near_starts.reshape(-1)])
    cols = np.concatenate([near_goals.reshape(-1), np.repeat(np.arange(n), k)])
    with pytest.raises(ValueError, match="no full matching"):
        min_weight_full_bipartite_matching(
            csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)))
    sparse = _sparse(starts, goals, neighbours=k)
    assert sparse.proven
    assert sparse.rounds > 1  # the first graph's optimum was not the true one
    assert sparse.cost == pytest.approx(_dense_optimum(starts, goals).cost, rel=1e-9)


def test_an_unfinished_certificate_is_not_reported_proven(monkeypatch):
    # One round only: the candidate graph's optimum misses edges the true optimum needs.
    starts, goals = _clusters(np.random.default_rng(5))
    best = _dense_optimum(starts, goals).cost
    monkeypatch.setattr(assignment, "MAX_ROUNDS", 1)
    with monkeypatch.context() as no_fallback:
        no_fallback.setattr(assignment, "DENSE_FALLBACK", 0)
        cut = _sparse(starts, goals, neighbours=4)
    assert cut.method == "sparse"
    assert cut.cost > best * (1 + 1e-6)  # the crafted case really needs more edges
    assert not cut.proven
    assert cut.lower_bound <= best * (1 + 1e-9)  # the reported bound stays a true bound
    assert cut.gap >= cut.cost - best - 1e-6 * best
    # solve_assignment does not hand back the unproven order: it falls back to dense
    fallback = _sparse(starts, goals, neighbours=4)
    assert fallback.method == "dense" and fallback.cost == pytest.approx(best, rel=1e-12)


def test_sparse_assignment_is_deterministic():
    starts, goals = _structured("grid-sphere", 256)
    first = _sparse(starts, goals)
    again = _sparse(starts.copy(), goals.copy())
    np.testing.assert_array_equal(first.order, again.order)
    assert (first.cost, first.rounds, first.edges) == (again.cost, again.rounds, again.edges)


def test_sparse_assignment_builds_nothing_n_by_n():
    import tracemalloc

    rng = np.random.default_rng(9)
    n = 2500
    starts, goals = rng.random((n, 3)) * 60, rng.random((n, 3)) * 60
    tracemalloc.start()
    try:
        result = _sparse(starts, goals)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.proven
    assert peak < n * n * 8 / 4  # a dense cost matrix alone would be n * n * 8 bytes


def test_assign_goals_keeps_its_signature_and_uses_dense_for_small_fleets():
    starts, goals = _structured("sideways", 50)
    assert solve_assignment(starts, goals).method == "dense"
    np.testing.assert_array_equal(assign_goals(starts, goals),
                                  solve_assignment(starts, goals).order)
    with pytest.raises(ValueError, match="differ in shape"):
        solve_assignment(starts, goals[:-1])


def test_assign_goals_warns_when_a_result_is_not_proven(monkeypatch):
    starts, goals = _clusters(np.random.default_rng(5))
    monkeypatch.setattr(assignment, "MAX_ROUNDS", 1)
    monkeypatch.setattr(assignment, "DENSE_FALLBACK", 0)  # no dense rescue at this size
    with pytest.warns(RuntimeWarning, match="not proven optimal: it may exceed the optimum by"):
        order = assign_goals(starts, goals, dense_below=2)
    assert sorted(order.tolist()) == list(range(len(starts)))


@pytest.mark.parametrize(("start", "goal"), [("grid", "torus"), ("grid", "cube"),
                                             ("torus", "cylinder"), ("carpet", "sphere")])
def test_sparse_matches_dense_between_lattice_formations(start, goal):
    """Lattices full of near-equal costs (at 2,000 vehicles grid -> torus used to stall
    scipy's sparse matcher on float weights)."""
    from planner.families.generators import formation

    starts, goals = formation(start, 300), formation(goal, 300) + np.array([0.0, 0.0, 0.5])
    sparse, dense = _sparse(starts, goals), _dense_optimum(starts, goals)
    assert sparse.proven
    assert sparse.cost == pytest.approx(dense.cost, rel=1e-9)


def test_the_sparse_matcher_gets_whole_quanta(monkeypatch):
    """scipy's weights are whole multiples of WEIGHT_QUANTUM, at least one; the certificate
    still judges the result on the exact costs."""
    from scipy.sparse import csgraph

    seen = []
    real = csgraph.min_weight_full_bipartite_matching

    def spy(graph, *args, **kwargs):
        seen.append(graph.data.copy())
        return real(graph, *args, **kwargs)

    monkeypatch.setattr(csgraph, "min_weight_full_bipartite_matching", spy)
    monkeypatch.setattr(assignment, "matcher", lambda: "scipy")  # lapmod takes floats
    starts, goals = _structured("grid-sphere", 200)
    sparse = _sparse(starts, goals)
    assert seen and sparse.proven
    for weights in seen:
        assert np.all(weights >= 1.0)
        np.testing.assert_array_equal(weights, np.rint(weights))
    assert sparse.cost == pytest.approx(_dense_optimum(starts, goals).cost, rel=1e-9)
