"""The sequential convex programming loop (paper section 3.4, Algorithm 1).

Iteration 0 is the separation-free QP (`planner.first_qp`). Every later iteration linearises
the separation constraint about the previous iterate and solves the resulting QP, until the
total-thrust cost changes by less than `cost_threshold` or `max_iterations` is reached.

What makes it fast without changing the answer:

- Rows only where needed. Each iteration starts with rows for the pair-steps that are close
  at the linearisation point (plus those that were needed in the previous iteration). After
  each solve *every* pair-step's linearised row is checked and any violated one is added
  and the affected group solved again, so the result is the optimum of the all-pairs QP.
- Independent groups. Vehicles linked by rows form groups (connected components); each is
  its own QP. A vehicle in no group keeps its separation-free optimum, which is exactly its
  QP's solution. A group whose members and rows did not change is not solved again.
- Continuous time. After each solve the exact motion between steps is checked; where a pair
  dips below R inside a step, the interval gets the Bernstein rows of the linearised
  constraint (control points p_k, p_k + dt/2 v_k, p_k+1 along the direction of step k), which
  keep the linearised distance >= R over the whole interval, hence the true distance too.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from planner.first_qp import solve_first_qp
from planner.flatness import GRAVITY
from planner.qp import SeparationRows, StageLayout, build_group_qp
from planner.result import IterationRecord
from planner.scenario import Scenario
from planner.separation import (
    PairSteps,
    all_pairs,
    interval_lower_bounds,
    interval_minima,
    linearised_coefficients,
    step_distances,
    violated_linearised,
)
from planner.solvers import SOLVED, QPSolver

__all__ = ["ScpOptions", "ScpOutcome", "run_scp", "thrust_cost"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
Keys = NDArray[np.int64]

KINDS = 3  # 0: step row, 1: Bernstein middle point, 2: Bernstein end point


@dataclass(frozen=True)
class ScpOptions:
    """Knobs of the SCP loop; the defaults are what `planner.plan` uses."""

    culling: bool = True
    """Rows only for close pair-steps (lazily completed). False: every pair at every step."""
    candidate_margin: float = 0.0
    """Pair-steps closer than R * (1 + margin) at the linearisation point start with a row."""
    continuous: bool = True
    """Enforce separation over continuous time (Bernstein rows where a pair dips)."""
    violation_tolerance: float = 1e-6
    """A linearised row or a continuous-time dip deeper than this gets a row (m)."""


@dataclass
class ScpOutcome:
    status: str
    message: str
    positions: FloatArray
    velocities: FloatArray
    accelerations: FloatArray
    iterations: list[IterationRecord]
    first_qp_seconds: float
    infeasible_groups: tuple[str, ...] = ()
    infeasible_vehicles: tuple[int, ...] = ()
    rows_by_kind: dict[str, int] = field(default_factory=dict)


def thrust_cost(accelerations: FloatArray) -> float:
    """The paper's total-thrust cost sum ||a + g||^2 over vehicles and steps."""
    a = np.asarray(accelerations)
    return float(np.sum(a[..., :2] ** 2) + np.sum((a[..., 2] + GRAVITY) ** 2))


class _RowKeys:
    """Encodes (i, j, k, kind) rows as int64 keys for fast set arithmetic."""

    def __init__(self, vehicles: int, steps: int) -> None:
        self.n = vehicles
        self.stages = steps + 1

    def encode(self, pairs: PairSteps, kind: int | IntArray) -> Keys:
        return pairs.keys(self.n, self.stages) * KINDS + np.asarray(kind, dtype=np.int64)

    def decode(self, keys: Keys) -> tuple[PairSteps, IntArray]:
        kind = (keys % KINDS).astype(np.intp)
        return PairSteps.from_keys(keys // KINDS, self.n, self.stages), kind


class _GroupSolver:
    """Solves groups, caching each group's solution by (members, rows) so that a lazy
    re-solve only touches the groups whose rows changed."""

    def __init__(self, scenario: Scenario, solver: QPSolver, codec: _RowKeys) -> None:
        self.scenario = scenario
        self.solver = solver
        self.codec = codec
        self.cache: dict[bytes, tuple[IntArray, FloatArray, FloatArray, FloatArray]] = {}
        self.solves = 0

    def solve(self, members: IntArray, keys: Keys, lin_positions: FloatArray
              ) -> tuple[str, tuple[FloatArray, FloatArray, FloatArray] | None]:
        signature = members.tobytes() + b"|" + keys.tobytes()
        cached = self.cache.get(signature)
        if cached is not None:
            return SOLVED, cached[1:]
        scenario = self.scenario
        pairs, kind = self.codec.decode(keys)
        coef = linearised_coefficients(lin_positions, scenario.separation_scale, pairs)
        local = np.full(scenario.starts.shape[0], -1, dtype=np.intp)
        local[members] = np.arange(len(members))
        rows = SeparationRows(local[pairs.i], local[pairs.j], pairs.k, kind, coef)
        qp = build_group_qp(scenario, members, rows)
        self.solves += 1
        result = self.solver.solve(qp)
        if result.status != SOLVED or result.x is None:
            return result.status, None
        p, v, a = StageLayout(scenario.steps, len(members)).unpack(result.x)
        self.cache[signature] = (members, p, v, a)
        return SOLVED, (p, v, a)


def _groups(keys: Keys, codec: _RowKeys) -> list[tuple[IntArray, Keys]]:
    """Connected components of the vehicles linked by rows, each with its sorted keys."""
    if keys.size == 0:
        return []
    pairs, _ = codec.decode(keys)
    n = codec.n
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs.i, pairs.j)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    involved = np.unique(np.concatenate([pairs.i, pairs.j]))
    row_label = label[pairs.i]
    order = np.argsort(row_label, kind="stable")
    sorted_labels = row_label[order]
    out = []
    for lab in np.unique(label[involved]):
        lo, hi = np.searchsorted(sorted_labels, [lab, lab + 1])
        members = involved[label[involved] == lab]
        out.append((members, np.sort(keys[order[lo:hi]])))
    return out


def _close_rows(positions: FloatArray, scenario: Scenario, margin: float, codec: _RowKeys,
                culling: bool) -> Keys:
    """Step rows to start an iteration with: close pair-steps, or all with culling off."""
    n, stages = positions.shape[0], positions.shape[1]
    if not culling:
        i, j = all_pairs(n)
        pairs = PairSteps(np.repeat(i, stages), np.repeat(j, stages), np.tile(
            np.arange(stages, dtype=np.intp), len(i)))
        return codec.encode(pairs, 0)
    below = scenario.min_separation * (1.0 + margin)
    pairs, _ = step_distances(positions, scenario.separation_scale, below)
    return codec.encode(pairs, 0)


def _continuous_dips(p: FloatArray, v: FloatArray, a: FloatArray, scenario: Scenario,
                     tolerance: float) -> PairSteps:
    """Pair-intervals whose exact continuous-time distance falls below R - tolerance."""
    below = scenario.min_separation - tolerance
    scale = scenario.separation_scale
    maybe = interval_lower_bounds(p, a, scenario.dt, scale, below)
    if len(maybe) == 0:
        return maybe
    minima, _ = interval_minima(p, v, a, scenario.dt, scale, maybe)
    return maybe.select(minima < below)


def _solve_with_lazy_rows(
    scenario: Scenario,
    options: ScpOptions,
    codec: _RowKeys,
    groups_solver: _GroupSolver,
    lin: tuple[FloatArray, FloatArray, FloatArray],
    base: tuple[FloatArray, FloatArray, FloatArray],
    keys: Keys,
) -> tuple[str, tuple[FloatArray, FloatArray, FloatArray], Keys, int, list[int]]:
    """One SCP iteration: solve, check all pairs and continuous time, add rows, repeat.

    Returns (status, (p, v, a), final keys, number of groups, members of a failed group).
    """
    lin_p = lin[0]
    while True:
        p, v, a = (x.copy() for x in base)
        groups = _groups(keys, codec)
        for members, group_keys in groups:
            status, solution = groups_solver.solve(members, group_keys, lin_p)
            if solution is None:
                return status, (p, v, a), keys, len(groups), members.tolist()
            p[members], v[members], a[members] = solution
        violated = violated_linearised(
            lin_p, p, scenario.separation_scale, scenario.min_separation,
            options.violation_tolerance,
        )
        new = [codec.encode(violated, 0)]
        if options.continuous:
            dips = _continuous_dips(p, v, a, scenario, options.violation_tolerance)
            if len(dips):
                new += [codec.encode(dips, kind) for kind in range(KINDS)]
        added = np.setdiff1d(np.concatenate(new), keys)
        if added.size == 0:
            return SOLVED, (p, v, a), keys, len(groups), []
        keys = np.union1d(keys, added)


def run_scp(
    scenario: Scenario,
    solver: QPSolver,
    options: ScpOptions | None = None,
    progress: Callable[[IterationRecord], None] | None = None,
) -> ScpOutcome:
    """Run the SCP loop on a validated scenario."""
    options = options or ScpOptions()
    began = time.perf_counter()
    first = solve_first_qp(scenario, solver)
    first_seconds = time.perf_counter() - began
    base = (first.positions, first.velocities, first.accelerations)
    if first.status != SOLVED:
        return ScpOutcome(
            status="infeasible",
            message=f"the separation-free QP has no solution (solver: {first.status})",
            positions=base[0], velocities=base[1], accelerations=base[2],
            iterations=[], first_qp_seconds=first_seconds,
            infeasible_groups=("boxes",), infeasible_vehicles=first.qp_vehicles,
        )

    def record(rec: IterationRecord) -> None:
        history.append(rec)
        if progress is not None:
            progress(rec)

    history: list[IterationRecord] = []
    cost = thrust_cost(first.accelerations)
    record(IterationRecord(0, cost, None, 0, first.qp_solves, 0, first_seconds))

    codec = _RowKeys(len(scenario.vehicles), scenario.steps)
    groups_solver = _GroupSolver(scenario, solver, codec)
    current = base
    carried = np.zeros(0, dtype=np.int64)
    status, message = "max_iterations", ""
    for iteration in range(1, scenario.max_iterations + 1):
        t0 = time.perf_counter()
        solves_before = groups_solver.solves
        keys = np.union1d(_close_rows(current[0], scenario, options.candidate_margin, codec,
                                      options.culling), carried)
        groups_solver.cache.clear()
        result, solution, keys, n_groups, failed = _solve_with_lazy_rows(
            scenario, options, codec, groups_solver, current, base, keys
        )
        if result != SOLVED:
            ids = [scenario.vehicles[i].id for i in failed]
            return ScpOutcome(
                status="infeasible",
                message=(
                    f"iteration {iteration}: the QP of vehicles {', '.join(ids)} has no "
                    f"solution with the linearised separation rows (solver: {result})"
                ),
                positions=current[0], velocities=current[1], accelerations=current[2],
                iterations=history, first_qp_seconds=first_seconds,
                infeasible_groups=("separation",), infeasible_vehicles=tuple(failed),
            )
        new_cost = thrust_cost(solution[2])
        change = abs(new_cost - cost)
        record(IterationRecord(
            iteration, new_cost, change, int(keys.size), groups_solver.solves - solves_before,
            n_groups, time.perf_counter() - t0,
        ))
        current, cost, carried = solution, new_cost, keys
        if change < scenario.cost_threshold:
            status = "converged"
            message = f"cost changed by {change:.3g} < {scenario.cost_threshold:g}"
            break
    else:
        message = f"stopped after {scenario.max_iterations} iterations without converging"
    _, kinds = codec.decode(carried)
    return ScpOutcome(
        status=status, message=message,
        positions=current[0], velocities=current[1], accelerations=current[2],
        iterations=history, first_qp_seconds=first_seconds,
        rows_by_kind={
            "step": int(np.sum(kinds == 0)),
            "continuous": int(np.sum(kinds != 0)),
        },
    )
