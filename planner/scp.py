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

from planner.boxes import broken_boxes, near_boxes
from planner.first_qp import solve_first_qp
from planner.flatness import GRAVITY
from planner.qp import BoxMask, SeparationRows, StageLayout, build_group_qp
from planner.result import IterationRecord
from planner.scenario import Scenario
from planner.separation import (
    PairSteps,
    all_pairs,
    linearised_coefficients,
    step_distances,
    violated_linearised,
    worst_per_run,
)
from planner.solvers import SOLVED, QPSolver

__all__ = ["ScpOptions", "ScpOutcome", "run_scp", "thrust_cost"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
Keys = NDArray[np.int64]

KINDS = 3  # 0: step row, 1: Bernstein middle point, 2: Bernstein end point
#: A separation row whose multiplier exceeds this is active and is carried to the next
#: iteration (re-linearised there): active sets change little between SCP iterations.
ACTIVE_DUAL = 1e-7



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
        self.cache: dict[bytes, tuple[tuple[FloatArray, FloatArray, FloatArray], Keys]] = {}
        self.solves = 0

    def solve(self, members: IntArray, keys: Keys, boxes: BoxMask, lin_positions: FloatArray
              ) -> tuple[str, tuple[FloatArray, FloatArray, FloatArray] | None, Keys]:
        """Solve one group; returns (status, (p, v, a) or None, keys of its active rows).

        boxes: (all vehicles) which bounds and jerk rows to include.
        """
        group_boxes = boxes.take(members)
        signature = b"|".join([
            members.tobytes(), keys.tobytes(),
            np.packbits(group_boxes.bounds).tobytes(), np.packbits(group_boxes.jerk).tobytes(),
        ])
        cached = self.cache.get(signature)
        if cached is not None:
            return SOLVED, cached[0], cached[1]
        scenario = self.scenario
        pairs, kind = self.codec.decode(keys)
        coef = linearised_coefficients(lin_positions, scenario.separation_scale, pairs)
        local = np.full(scenario.starts.shape[0], -1, dtype=np.intp)
        local[members] = np.arange(len(members))
        rows = SeparationRows(local[pairs.i], local[pairs.j], pairs.k, kind, coef)
        qp = build_group_qp(scenario, members, rows, group_boxes)
        self.solves += 1
        result = self.solver.solve(qp)
        if result.status != SOLVED or result.x is None:
            return result.status, None, keys[:0]
        solution = StageLayout(scenario.steps, len(members)).unpack(result.x)
        duals = result.separation_duals
        active = keys if duals is None else keys[duals > ACTIVE_DUAL]
        self.cache[signature] = (solution, active)
        return SOLVED, solution, active


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


def _seed_rows(positions: FloatArray, scenario: Scenario, options: ScpOptions,
               codec: _RowKeys) -> Keys:
    """Step rows an iteration starts with (besides the rows carried over as active).

    With culling: the deepest step of every run of steps where a pair is closer than
    R * (1 + margin) at the linearisation point. Without: every pair at every step.
    """
    n, stages = positions.shape[0], positions.shape[1]
    if not options.culling:
        i, j = all_pairs(n)
        pairs = PairSteps(np.repeat(i, stages), np.repeat(j, stages), np.tile(
            np.arange(stages, dtype=np.intp), len(i)))
        return _step_rows(pairs, codec, options.continuous)
    below = scenario.min_separation * (1.0 + options.candidate_margin)
    pairs, distances = step_distances(positions, scenario.separation_scale, below)
    return _step_rows(worst_per_run(pairs, distances), codec, options.continuous)


@dataclass
class _IterationResult:
    status: str
    solution: tuple[FloatArray, FloatArray, FloatArray]
    keys: Keys
    """Every row used in the last round."""
    active: Keys
    """Rows with a positive multiplier in the last round."""
    groups: int
    failed: list[int]


def _step_rows(pairs: PairSteps, codec: _RowKeys, continuous: bool) -> Keys:
    """Rows for close pair-steps: the step row and, for continuous time, the Bernstein rows
    of the two intervals around the step (a pair closest near step k is closest inside
    [k-1, k] or [k, k+1]; adding them now saves a round of re-solves later)."""
    keys = [codec.encode(pairs, 0)]
    if continuous and len(pairs):
        last = codec.stages - 2  # intervals are 0..K-1
        for shift in (0, -1):
            k = pairs.k + shift
            ok = (k >= 0) & (k <= last)
            interval = PairSteps(pairs.i[ok], pairs.j[ok], k[ok])
            keys += [codec.encode(interval, kind) for kind in range(KINDS)]
    return np.unique(np.concatenate(keys))


def _with_interval_companions(keys: Keys, codec: _RowKeys) -> Keys:
    """`keys` plus, for every Bernstein row, the other rows of its interval (all 3 kinds):
    the control-point rows only guarantee the interval together."""
    pairs, kind = codec.decode(keys)
    bernstein = kind != 0
    if not bernstein.any():
        return keys
    intervals = pairs.select(bernstein)
    extra = [codec.encode(intervals, k) for k in range(KINDS)]
    return np.union1d(keys, np.concatenate(extra))


def _solve_with_lazy_rows(
    scenario: Scenario,
    options: ScpOptions,
    codec: _RowKeys,
    groups_solver: _GroupSolver,
    lin_positions: FloatArray,
    base: tuple[FloatArray, FloatArray, FloatArray],
    keys: Keys,
    boxes: BoxMask,
) -> _IterationResult:
    """One SCP iteration: solve, check every separation row and box, add what is broken,
    solve again, until nothing is broken.

    boxes: the bounds and jerk rows to start with; the others are checked after each solve
    (most are far from binding, and each one the QP carries costs interior-point work).
    """
    tolerance = options.violation_tolerance
    while True:
        p, v, a = (x.copy() for x in base)
        groups = _groups(keys, codec)
        active = []
        for members, group_keys in groups:
            status, solution, group_active = groups_solver.solve(
                members, group_keys, boxes, lin_positions
            )
            if solution is None:
                return _IterationResult(status, (p, v, a), keys, keys[:0], len(groups),
                                        members.tolist())
            p[members], v[members], a[members] = solution
            active.append(group_active)
        new = []
        for kind, (violated, values) in enumerate(violated_linearised(
            lin_positions, p, v, scenario.dt, scenario.separation_scale,
            scenario.min_separation, tolerance, options.continuous,
        )):
            if len(violated) == 0:
                continue
            if options.culling:
                violated = worst_per_run(violated, values)
            if kind == 0:
                new.append(_step_rows(violated, codec, options.continuous))
            else:  # an interval row comes with the other rows of its interval
                new += [codec.encode(violated, k) for k in range(KINDS)]
        if not new:
            new = [keys[:0]]
        added = np.setdiff1d(np.concatenate(new), keys)
        broken = broken_boxes(scenario, p, v, a, tolerance)
        new_bounds = broken.bounds & ~boxes.bounds
        new_jerk = broken.jerk & ~boxes.jerk
        boxes_added = bool(new_bounds.any() or new_jerk.any())
        if boxes_added:
            boxes = BoxMask(boxes.bounds | new_bounds, boxes.jerk | new_jerk)
        if added.size == 0 and not boxes_added:
            all_active = np.concatenate(active) if active else keys[:0]
            return _IterationResult(SOLVED, (p, v, a), keys, all_active, len(groups), [])
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
    used = carried
    status, message = "max_iterations", ""
    for iteration in range(1, scenario.max_iterations + 1):
        t0 = time.perf_counter()
        solves_before = groups_solver.solves
        keys = np.union1d(_seed_rows(current[0], scenario, options, codec), carried)
        groups_solver.cache.clear()
        boxes = near_boxes(scenario, *current)
        outcome = _solve_with_lazy_rows(
            scenario, options, codec, groups_solver, current[0], base, keys, boxes
        )
        result, solution, keys, failed = (
            outcome.status, outcome.solution, outcome.keys, outcome.failed
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
            outcome.groups, time.perf_counter() - t0,
        ))
        current, cost = solution, new_cost
        # Carry the active rows; a Bernstein row carries its interval's other two rows.
        carried = _with_interval_companions(outcome.active, codec)
        used = keys
        if change < scenario.cost_threshold:
            status = "converged"
            message = f"cost changed by {change:.3g} < {scenario.cost_threshold:g}"
            break
    else:
        message = f"stopped after {scenario.max_iterations} iterations without converging"
    _, kinds = codec.decode(used)
    return ScpOutcome(
        status=status, message=message,
        positions=current[0], velocities=current[1], accelerations=current[2],
        iterations=history, first_qp_seconds=first_seconds,
        rows_by_kind={
            "step": int(np.sum(kinds == 0)),
            "continuous": int(np.sum(kinds != 0)),
        },
    )
