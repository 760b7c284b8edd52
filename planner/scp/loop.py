"""The sequential convex programming loop (paper section 3.4, Algorithm 1).

Iteration 0 is the separation-free QP (`planner.scp.first_qp`). Every later iteration linearises
the separation constraint about the previous iterate and solves the resulting QP, until the
total-thrust cost changes by less than `cost_threshold` or `max_iterations` is reached.

Each iteration's QP is, by definition, the one with *every* linearised separation row (of
every pair, at every step or interval, see `planner.scp.separation`) and *every* box. Solving it
that way is slow (the rows couple vehicles and cause fill-in), and almost all of those
constraints are slack at the optimum, so it is solved as a sequence of smaller QPs:

- Rows only where needed, like an active-set method. A QP starts with the rows that were
  active (positive multiplier) in the previous iteration, the deepest point of every close
  approach at the linearisation point (`planner.scp.pruning`), and the boxes that nearly bind.
  After each solve every row of every pair and every box is checked; the violated ones are
  added and the affected groups solved again. When nothing is violated, the solution is
  optimal for the QP with every row (feasible for it, optimal for a relaxation of it).
- Independent groups (`planner.scp.group_solver`). Vehicles linked by rows form groups, each
  its own QP; a vehicle in no group keeps its separation-free optimum (its QP's solution).
  A group whose members and constraints did not change is not solved again.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from planner.methods.routes import seed_routes
from planner.model.flatness import thrust_cost
from planner.model.scenario import Scenario
from planner.options import ScpOptions
from planner.result import IterationProgress, IterationRecord, PlanStatus, Progress
from planner.scp.boxes import broken_boxes, near_boxes
from planner.scp.first_qp import FirstSolution, timed_first_qp
from planner.scp.group_solver import Codec, GroupSolver, Keys, Trajectories, groups_of
from planner.scp.one_sided import OneSidedRows
from planner.scp.pruning import broken_rows, margins, seed_keys
from planner.scp.qp import BoxMask
from planner.scp.solvers import SOLVED, QPSolver
from planner.types import FloatArray

__all__ = ["ScpOptions", "ScpOutcome", "run_scp", "thrust_cost"]

#: Horizons of more steps solve the primal QP: the dual's functional matrix is dense in the
#: steps (5K x 5K doubles: 32 MB at 400 steps, 5 GB at the 5,000 allowed) and the primal is
#: faster there anyway (2 vehicles crossing: 0.02 s against 0.29 s at 600 steps).
DUAL_MAX_STEPS = 400
#: Vehicles per prioritized batch by default for a fleet with a dominant motion: measured
#: fastest on the sideways family (see docs/benchmarks/planner.md, Prioritized batches);
#: an obstacle-free crowd without one goes a vehicle at a time
#: (`planner.methods.prioritized.batch_size`).
DEFAULT_BATCH = 2
#: Sideways bend of the paths (in units of R) used to linearise again when an iteration's QP
#: came out infeasible.
BEND_AMPLITUDE = 0.2


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


def _keep_right_bend(positions: FloatArray, scenario: Scenario, amplitude: float) -> FloatArray:
    """Every path bent sideways to the right of its vehicle's travel by up to `amplitude`
    (a sine bump, zero at start and goal), as the first linearisation point."""
    travel = scenario.goals - scenario.starts
    right = np.stack([travel[:, 1], -travel[:, 0], np.zeros(len(travel))], axis=1)
    norm = np.linalg.norm(right, axis=1, keepdims=True)
    right = np.where(norm > 1e-9, right / np.where(norm > 1e-9, norm, 1.0), 0.0)
    bump = np.sin(np.pi * np.linspace(0.0, 1.0, positions.shape[1]))
    return positions + amplitude * bump[None, :, None] * right[:, None, :]


#: `_solve_iteration`'s hook: (round, groups solved, groups, separation rows, largest group).
Step = Callable[[int, int, int, int, int], None]


@dataclass
class _IterationResult:
    status: str
    solution: Trajectories
    keys: Keys
    """Every row used in the last round."""
    active: Keys
    """Rows with a positive multiplier in the last round."""
    boxes: BoxMask
    groups: int
    largest_group: int
    failed: list[int]
    obstacle_keys: Keys = field(default_factory=lambda: np.zeros(0, np.int64))
    """Every obstacle row used in the last round."""
    obstacle_active: Keys = field(default_factory=lambda: np.zeros(0, np.int64))
    """Obstacle rows with a positive multiplier in the last round."""


def _solve_iteration(
    scenario: Scenario,
    options: ScpOptions,
    codec: Codec,
    groups_solver: GroupSolver,
    lin: Trajectories,
    base: Trajectories,
    keys: Keys,
    boxes: BoxMask,
    okeys: Keys | None = None,
    step: Step | None = None,
) -> _IterationResult:
    """One SCP iteration: solve, check every row and box, add what is broken, repeat.
    okeys: the obstacle rows it starts with (with obstacles). step: told (round, groups
    solved, groups, separation rows, largest group) as each round starts and after each
    group's QP."""
    tolerance = options.violation_tolerance
    forced = np.zeros(0, dtype=np.intp)
    obstacles = groups_solver.obstacles
    okeys = np.zeros(0, dtype=np.int64) if okeys is None else okeys
    # Rows are only checked where they can be violated: an interval whose rows all hold by
    # `margin` at `lin` stays clear while its two vehicles move less than that in total.
    pruning = margins(scenario, options, lin)
    rounds = 0
    while True:
        rounds += 1
        p, v, a = (x.copy() for x in base)
        owners = obstacles.vehicles_of(okeys) if obstacles is not None else forced
        groups = groups_of(keys, codec, np.union1d(forced, owners).astype(np.intp))
        rows = int(keys.size) * (3 if options.continuous else 1)
        largest = max((len(m) for m, _ in groups), default=0)
        if step is not None:
            step(rounds, 0, len(groups), rows, largest)
        active, held = [], []
        for members, group_keys in groups:
            group_okeys = okeys[np.isin(owners, members)] if obstacles is not None else None
            status, solution, group_active, group_held = groups_solver.solve(
                members, group_keys, boxes, lin, group_okeys
            )
            if solution is None:
                return _IterationResult(status, (p, v, a), keys, keys[:0], boxes, len(groups),
                                        len(members), members.tolist(), okeys)
            p[members], v[members], a[members] = solution
            active.append(group_active)
            held.append(group_held)
            if step is not None:
                step(rounds, len(active), len(groups), rows, largest)
        # Every violated row goes in at once: fewer rounds than adding the worst of each
        # run (measured on the paper and scale cases), at a similar QP size.
        violated = broken_rows(scenario, options, pruning, lin, (p, v))
        added = np.setdiff1d(codec.encode(violated), keys)
        new_boxes = broken_boxes(scenario, p, v, a, tolerance) - boxes
        o_added = (obstacles.violated(lin[0], p, v, okeys, tolerance) if obstacles is not None
                   else okeys[:0])
        if added.size == 0 and not new_boxes.any() and o_added.size == 0:
            all_active = np.concatenate(active) if active else keys[:0]
            all_held = np.concatenate(held) if held else okeys[:0]
            return _IterationResult(SOLVED, (p, v, a), keys, all_active, boxes, len(groups),
                                    largest, [], okeys, all_held)
        keys = np.union1d(keys, added)
        okeys = np.union1d(okeys, o_added)
        if new_boxes.any():
            boxes = boxes | new_boxes
            touched = np.flatnonzero(
                new_boxes.bounds.any(axis=(1, 2, 3)) | new_boxes.jerk.any(axis=(1, 2))
                | new_boxes.wall.any(axis=(1, 2))
            )
            forced = np.union1d(forced, touched)


#: Least time (s) between two `IterationProgress` reports of one iteration.
PROGRESS_EVERY_S = 1.0
#: A round whose largest group has this many vehicles is reported as it starts: its QP alone
#: can take minutes (100 vehicles crossing one point), where smaller ones take milliseconds.
PROGRESS_GROUP_VEHICLES = 32


def _working(progress: Progress, iteration: int, began: float, groups_solver: GroupSolver,
             solves_before: int) -> Step:
    """The step hook of iteration `iteration`: an `IterationProgress` to `progress` as a
    round with a big group starts, and after a group's QP once PROGRESS_EVERY_S has passed
    since the iteration began or the last report (a clock read per QP: nothing measurable
    beside the QP)."""
    last = began

    def step(rounds: int, done: int, groups: int, rows: int, largest: int) -> None:
        nonlocal last
        now = time.perf_counter()
        starting_big = done == 0 and largest >= PROGRESS_GROUP_VEHICLES
        if not starting_big and now - last < PROGRESS_EVERY_S:
            return
        last = now
        progress(IterationProgress(iteration, rounds, done, groups, rows, largest,
                                   groups_solver.solves - solves_before, now - began))

    return step


def _first_infeasible(scenario: Scenario, first: FirstSolution, seconds: float) -> ScpOutcome:
    """The outcome when iteration 0 (the separation-free QP) has no solution, naming the
    vehicle and the bounds when the solver's diagnosis found them."""
    message = f"the separation-free QP has no solution (solver: {first.status})"
    group = "boxes"
    if first.diagnosis is not None:
        group, index = first.diagnosis.group, first.diagnosis.vehicle
        why = (f"under the {group} bounds (feasible without them)" if group != "boxes"
               else "under the combined box constraints")
        message = (f"vehicles[{index}] ({scenario.vehicles[index].id!r}) cannot reach its "
                   f"goal in the horizon {why}")
    return ScpOutcome(
        status=PlanStatus.INFEASIBLE, message=message,
        positions=first.positions, velocities=first.velocities,
        accelerations=first.accelerations,
        iterations=[], first_qp_seconds=seconds,
        infeasible_groups=(group,),
    )


@dataclass
class _Iterations:
    """What the iterations of one SCP run share: the scenario, the separation-free optimum
    (`base`, every group's starting values), the group solver and the one-sided rows."""

    scenario: Scenario
    options: ScpOptions
    codec: Codec
    groups_solver: GroupSolver
    base: Trajectories
    one_sided: OneSidedRows | None
    dual: bool
    step: Step | None = None
    """Told how an iteration's rounds go (`_solve_iteration`)."""

    @staticmethod
    def start(scenario: Scenario, solver: QPSolver, options: ScpOptions, base: Trajectories
              ) -> _Iterations:
        """The group solver (through the dual where it serves) and the one-sided rows."""
        codec = Codec(len(scenario.vehicles), scenario.steps)
        dual = options.dual and solver.name == "piqp" and scenario.steps <= DUAL_MAX_STEPS
        groups_solver = GroupSolver(scenario, solver, codec, options.continuous,
                                    options.split_above, options.block_size, dual)
        one_sided = None
        if scenario.obstacles or scenario.fixed:
            one_sided = groups_solver.obstacles = OneSidedRows(scenario, options.obstacle_seed)
        return _Iterations(scenario, options, codec, groups_solver, base, one_sided, dual)

    def solve(self, current: Trajectories, carried: Keys, held: Keys
              ) -> tuple[_IterationResult, bool]:
        """One SCP iteration linearised about `current`, starting from the rows `carried`
        (separation) and `held` (one-sided) found active in the last one. When its QP is
        infeasible, once more about keep-right paths. Returns (result, retried)."""
        last = self._about(current, current, carried, held)
        if last.status == SOLVED:
            return last, False
        # Degenerate crossings (vehicles of a symmetric swap all meeting at one point) can
        # leave the linearised QP empty. Linearise once more about paths bent to the right
        # of each vehicle's travel, which turns such a meeting into a roundabout; any
        # linearisation point gives valid (inner) rows.
        bent = (_keep_right_bend(current[0], self.scenario,
                                 BEND_AMPLITUDE * self.scenario.min_separation),
                current[1], current[2])
        return self._about(bent, current, carried, held), True

    def failure(self, iteration: int, last: _IterationResult) -> str:
        """Why iteration `iteration` failed with `last`, naming the group's vehicles."""
        ids = [self.scenario.vehicles[i].id for i in last.failed]
        return (f"iteration {iteration}: the QP of vehicles {', '.join(ids)} has no "
                f"solution with the linearised separation"
                f"{'' if self.one_sided is None else ' and obstacle'} rows "
                f"(solver: {last.status})")

    def _about(self, lin: Trajectories, current: Trajectories, carried: Keys, held: Keys
               ) -> _IterationResult:
        """The iteration's QPs linearised about `lin`, with the boxes near binding at
        `current`."""
        scenario, options, codec = self.scenario, self.options, self.codec
        keys = np.union1d(seed_keys(lin, scenario, options, codec), carried)
        okeys = (None if self.one_sided is None
                 else np.union1d(self.one_sided.seed(lin), held))
        self.groups_solver.cache.clear()
        return _solve_iteration(
            scenario, options, codec, self.groups_solver, lin, self.base, keys,
            near_boxes(scenario, *current, dual=self.dual), okeys, self.step,
        )


@dataclass
class _History:
    """One run's iteration records, each told to `progress` as it comes, and the outcomes
    that carry them: every way out of the loop reports the same history."""

    first_qp_seconds: float
    progress: Progress | None
    records: list[IterationRecord] = field(default_factory=list)

    def record(self, rec: IterationRecord) -> None:
        """Keeps `rec` and tells `progress`."""
        self.records.append(rec)
        if self.progress is not None:
            self.progress(rec)

    def outcome(self, status: str, message: str, at: Trajectories,
                infeasible: tuple[str, ...] = ()) -> ScpOutcome:
        """The run's outcome at trajectories `at`, with the records so far."""
        return ScpOutcome(status=status, message=message, positions=at[0],
                          velocities=at[1], accelerations=at[2], iterations=self.records,
                          first_qp_seconds=self.first_qp_seconds, infeasible_groups=infeasible)


def run_scp(
    scenario: Scenario,
    solver: QPSolver,
    options: ScpOptions | None = None,
    progress: Progress | None = None,
    guess: Trajectories | None = None,
    first_qp: tuple[FirstSolution, float] | None = None,
    routed: bool = False,
) -> ScpOutcome:
    """Run the SCP loop on a validated scenario (goals as the vehicles fly to them).


    guess: (p, v, a) to linearise the first SCP iteration about instead of the
    separation-free optimum (e.g. CAPT's synchronised straight moves); any point gives
    valid rows, a separated one gives rows that the guess itself satisfies.
    first_qp: iteration 0 already solved for this scenario, and its seconds
    (`timed_first_qp`), so that it is not solved again.
    routed: the guess already follows routes around the obstacles and every goal is known
    reachable (`planner.methods.spacetime`): no route seeding of its own.
    """
    options = options or ScpOptions()
    first, first_seconds = first_qp or timed_first_qp(scenario, solver)
    if first.status != SOLVED:
        return _first_infeasible(scenario, first, first_seconds)
    base = (first.positions, first.velocities, first.accelerations)
    history = _History(first_seconds, progress)
    cost = thrust_cost(first.accelerations)
    history.record(IterationRecord(0, cost, None, 0, first.qp_solves, 0, first_seconds))
    current = base if guess is None else guess
    if scenario.obstacles and not routed:  # routes, or the verdict on an unreachable goal
        seeded = seed_routes(scenario, current)
        if seeded.unreachable is not None:
            return history.outcome(PlanStatus.INFEASIBLE, seeded.unreachable, base,
                                   ("obstacles",))
        current = seeded.guess
    loop = _Iterations.start(scenario, solver, options, base)
    groups_solver, one_sided = loop.groups_solver, loop.one_sided
    carried = held = np.zeros(0, dtype=np.int64)
    retried = 0
    status, message = PlanStatus.MAX_ITERATIONS, ""
    for iteration in range(1, scenario.max_iterations + 1):
        t0 = time.perf_counter()
        solves_before = groups_solver.solves
        if progress is not None:
            loop.step = _working(progress, iteration, t0, groups_solver, solves_before)
        last, again = loop.solve(current, carried, held)
        retried += again
        if last.status != SOLVED:
            return history.outcome(PlanStatus.INFEASIBLE, loop.failure(iteration, last),
                                   current, ("separation",) if one_sided is None
                                   else ("separation", "obstacles"))
        new_cost = thrust_cost(last.solution[2])
        change = abs(new_cost - cost)
        rows_per_key = 3 if options.continuous else 1
        history.record(IterationRecord(
            iteration, new_cost, change, int(last.keys.size) * rows_per_key,
            groups_solver.solves - solves_before, last.groups, time.perf_counter() - t0,
            last.largest_group,
        ))
        current, cost, carried = last.solution, new_cost, last.active
        held = last.obstacle_active
        if change < scenario.cost_threshold:
            status = PlanStatus.CONVERGED
            message = f"cost changed by {change:.3g} < {scenario.cost_threshold:g}"
            break
    else:
        message = f"stopped after {scenario.max_iterations} iterations without converging"
    if retried:
        message += (f"; {retried} iteration(s) linearised again about keep-right paths after "
                    f"an infeasible QP")
    return history.outcome(status, message, current)
