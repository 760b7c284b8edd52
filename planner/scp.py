"""The sequential convex programming loop (paper section 3.4, Algorithm 1).

Iteration 0 is the separation-free QP (`planner.first_qp`). Every later iteration linearises
the separation constraint about the previous iterate and solves the resulting QP, until the
total-thrust cost changes by less than `cost_threshold` or `max_iterations` is reached.

Each iteration's QP is, by definition, the one with *every* linearised separation row (of
every pair, at every step or interval, see `planner.separation`) and *every* box. Solving it
that way is slow (the rows couple vehicles and cause fill-in), and almost all of those
constraints are slack at the optimum, so it is solved as a sequence of smaller QPs:

- Rows only where needed, like an active-set method. A QP starts with the rows that were
  active (positive multiplier) in the previous iteration, the deepest point of every close
  approach at the linearisation point, and the boxes that nearly bind. After each solve
  every row of every pair and every box is checked; the violated ones are added and the
  affected groups solved again. When nothing is violated, the solution is optimal for the
  QP with every row (it is feasible for it and optimal for a relaxation of it).
- Independent groups. Vehicles linked by rows form groups (connected components); each is
  its own QP. A vehicle in no group keeps its separation-free optimum, which is exactly its
  QP's solution. A group whose members and constraints did not change is not solved again.
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
from planner.dual import ActiveRows, FleetMoves, solve_group_dual
from planner.first_qp import FirstSolution, timed_first_qp
from planner.flatness import GRAVITY
from planner.obstacle_rows import SEED_FRACTION, concat_rows
from planner.one_sided import OneSidedRows
from planner.qp import BoxMask, SeparationRows, StageLayout, build_group_qp
from planner.result import IterationRecord, PlanStatus
from planner.routes import seed_routes
from planner.scenario import Scenario
from planner.separation import (
    CHUNK,
    NEAR_MIN_VEHICLES,
    PairSteps,
    all_pairs,
    close_among,
    close_rows,
    directions,
    far_margin_bound,
    interval_margins,
    near_windows,
    pair_index,
    row_displacements,
    values_among,
    violated_among,
    window_rows,
    worst_per_run,
)
from planner.solvers import SOLVED, QPSolver
from planner.types import FloatArray, IntArray

__all__ = ["ScpOptions", "ScpOutcome", "run_scp", "thrust_cost"]

Keys = NDArray[np.int64]
Trajectories = tuple[FloatArray, FloatArray, FloatArray]

#: A separation row whose multiplier exceeds this is active and is carried to the next
#: iteration (re-linearised there): active sets change little between SCP iterations.
ACTIVE_DUAL = 1e-7
#: Groups with more separation rows per vehicle than this solve the primal QP even when the
#: dual is on: where every vehicle meets dozens of others (a crowd crossing one point) the
#: dual's matrix couples nearly every row and its factorisation fills in. Measured on
#: grid -> sphere 64/100 (fixed): dual faster below ~30 rows per vehicle, up to 7x slower
#: at 43.
DUAL_MAX_ROWS_PER_VEHICLE = 25
#: Horizons of more steps solve the primal QP: the dual's functional matrix is dense in the
#: steps (5K x 5K doubles: 32 MB at 400 steps, 5 GB at the 5,000 allowed) and the primal is
#: faster there anyway (2 vehicles crossing: 0.02 s against 0.29 s at 600 steps).
DUAL_MAX_STEPS = 400
#: Vehicles per prioritized batch by default for a fleet with a dominant motion: measured
#: fastest on the sideways family (see docs/benchmarks/planner.md, Prioritized batches);
#: an obstacle-free crowd without one goes a vehicle at a time
#: (`planner.prioritized.batch_size`).
DEFAULT_BATCH = 2
#: Sideways bend of the paths (in units of R) used to linearise again when an iteration's QP
#: came out infeasible.
BEND_AMPLITUDE = 0.2
#: The broad phase's reach beyond R and the vehicles' own step terms, in units of R (see
#: `_margins`).
FAR_SLACK = 1.0
#: Steps per time window of the margins' broad phase (`_margins`): exact margins are
#: computed only in the windows where a pair is near.
MARGIN_WINDOW = 4


@dataclass(frozen=True)
class ScpOptions:
    """Knobs of the SCP loop itself; the defaults are what `planner.plan` uses (the choice of
    planning method is `planner.options.PlanningOptions`)."""

    continuous: bool = True
    """Interval rows (separation over continuous time) instead of the paper's step rows."""
    culling: bool = True
    """Rows only where needed (lazily completed). False: every pair at every step."""
    candidate_margin: float = 0.0
    """Pairs closer than R * (1 + margin) at the linearisation point seed a row."""
    violation_tolerance: float = 1e-6
    """A row or box broken by more than this is added to the QP (m, m/s, ...)."""
    split_above: int = 0
    """Groups of more vehicles are solved by block Gauss-Seidel sweeps (feasible, not
    necessarily optimal for the group's QP); 0 (the default): every group whole. Measured
    in the README (Performance): no clear gain at 1,000 vehicles, so off by default."""
    block_size: int = 32
    """Vehicles per block of a split group."""
    dual: bool = True
    """Solve each group's QP through its dual (`planner.dual`, one variable per row; the
    same optimum) instead of the primal staged QP with the configured backend. Only with
    the PIQP backend; other backends always solve the primal, and so does a plan of more
    than DUAL_MAX_STEPS steps, or a group whose dual is too dense (DUAL_MAX_ROWS_PER_VEHICLE)
    or did not solve (infeasible, ...)."""
    obstacle_seed: float = SEED_FRACTION
    """Obstacle rows within this many clearances of binding at the linearisation point
    start an iteration's QP (the rest are added when broken). More suits small QPs (the
    prioritized batches), where a re-solve costs more than the extra rows."""

    def __post_init__(self) -> None:
        if not 0.0 < self.obstacle_seed < float("inf"):
            raise ValueError(f"obstacle_seed: must be a positive number of clearances, "
                             f"got {self.obstacle_seed!r}")


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


def thrust_cost(accelerations: FloatArray) -> float:
    """The paper's total-thrust cost sum ||a + g||^2 over vehicles and steps."""
    a = np.asarray(accelerations)
    return float(np.sum(a[..., :2] ** 2) + np.sum((a[..., 2] + GRAVITY) ** 2))


class _Codec:
    """Encodes (i, j, k) pair-steps as int64 keys for fast set arithmetic."""

    def __init__(self, vehicles: int, steps: int) -> None:
        self.n = vehicles
        self.stages = steps + 1

    def encode(self, pairs: PairSteps) -> Keys:
        return pairs.keys(self.n, self.stages)

    def decode(self, keys: Keys) -> PairSteps:
        return PairSteps.from_keys(keys, self.n, self.stages)


class _GroupSolver:
    """Builds and solves one group's QP; caches solutions by (members, constraints) so a
    re-solve only touches the groups whose constraints changed."""

    def __init__(self, scenario: Scenario, solver: QPSolver, codec: _Codec, continuous: bool,
                 split_above: int = 0, block_size: int = 32, dual: bool = False) -> None:
        self.scenario = scenario
        self.solver = solver
        self.codec = codec
        self.continuous = continuous
        self.cache: dict[bytes, tuple[Trajectories, Keys, Keys]] = {}
        self.solves = 0
        self.split_above = split_above
        self.block_size = block_size
        self.dual = dual
        self.obstacles: OneSidedRows | None = None
        """The scenario's one-sided rows: obstacles and fixed trajectories (None without
        either)."""
        self.memory = ActiveRows()
        """Rows found active by earlier dual solves (kept across iterations): the warm
        start of the next solve that holds them."""
        self.fleet: FleetMoves | None = None
        """Every vehicle's straight move, for the dual solves (computed at the first)."""

    def solve(self, members: IntArray, keys: Keys, boxes: BoxMask, lin: Trajectories,
              obstacle_keys: Keys | None = None
              ) -> tuple[str, Trajectories | None, Keys, Keys]:
        """Returns (status, the group's (p, v, a) or None, keys of its active separation
        rows, keys of its active obstacle rows).

        lin: every vehicle's previous iterate, the linearisation point and the warm start
        (used by OSQP; the interior-point backends start from their own point).
        obstacle_keys: the group's obstacle rows (`planner.obstacle_rows`).
        """
        lin_positions = lin[0]
        group_boxes = boxes.take(members)
        okeys = np.zeros(0, dtype=np.int64) if obstacle_keys is None else obstacle_keys
        signature = b"|".join([
            members.tobytes(), keys.tobytes(), np.packbits(group_boxes.bounds).tobytes(),
            np.packbits(group_boxes.jerk).tobytes(), np.packbits(group_boxes.wall).tobytes(),
            okeys.tobytes(),
        ])
        cached = self.cache.get(signature)
        if cached is not None:
            return SOLVED, cached[0], cached[1], cached[2]
        if self.split_above and len(members) > self.split_above and okeys.size == 0:
            split = self._solve_blocks(members, keys, boxes, lin)
            if split is not None:
                self.cache[signature] = (*split, okeys)
                return SOLVED, split[0], split[1], okeys
        scenario = self.scenario
        pairs = self.codec.decode(keys)
        coef = np.zeros((0, 3))
        if len(pairs):
            u = directions(lin_positions, scenario.separation_scale, pairs, self.continuous,
                           scenario.min_separation, _moving(scenario))
            coef = u / scenario.separation_scale
        local = np.full(self.codec.n, -1, dtype=np.intp)
        local[members] = np.arange(len(members))
        kinds = (0, 1, 2) if self.continuous else (0,)
        count = len(pairs)
        rows = SeparationRows(
            i=np.tile(local[pairs.i], len(kinds)),
            j=np.tile(local[pairs.j], len(kinds)),
            k=np.tile(pairs.k, len(kinds)),
            kind=np.repeat(np.array(kinds, dtype=np.intp), count),
            coef=np.tile(coef, (len(kinds), 1)),
        )
        pair_rows = len(rows)
        if okeys.size and self.obstacles is not None:
            rows = concat_rows(rows, self.obstacles.rows(lin_positions, okeys, local))
        self.solves += 1
        outcome = None
        # Obstacle rows bind one vehicle each: they couple no vehicles in the dual's matrix.
        if self.dual and pair_rows <= DUAL_MAX_ROWS_PER_VEHICLE * len(members):
            # Row names: 3 key + kind for pair rows, negative for one-sided rows.
            kind_of = np.arange(len(kinds), dtype=np.int64)
            row_ids = np.concatenate([(3 * keys[None, :] + kind_of[:, None]).reshape(-1),
                                      (-1 - 3 * okeys[None, :] - np.arange(3)[:, None]).reshape(-1)
                                      if okeys.size and self.obstacles is not None
                                      else keys[:0]])
            if self.fleet is None:
                self.fleet = FleetMoves(scenario)
            outcome = solve_group_dual(scenario, members, rows, group_boxes,
                                       row_ids=row_ids, memory=self.memory, fleet=self.fleet)
        if outcome is not None and outcome.status == SOLVED and outcome.solution is not None:
            solution, duals = outcome.solution, outcome.separation_duals
        else:  # the primal QP; also the judge when the dual did not solve (infeasible, ...)
            qp = build_group_qp(scenario, members, rows, group_boxes)
            layout = StageLayout(scenario.steps, len(members))
            warm = layout.pack(*(x[members] for x in lin))
            result = self.solver.solve(qp, warm_start=warm)
            if result.status != SOLVED or result.x is None:
                return result.status, None, keys[:0], okeys[:0]
            solution, duals = layout.unpack(result.x), result.separation_duals
        active = keys
        if duals is not None and count:
            per_key = duals[:pair_rows].reshape(len(kinds), count).max(axis=0)
            active = keys[per_key > ACTIVE_DUAL]
        held = okeys
        if duals is not None and okeys.size:
            held = okeys[duals[pair_rows:].reshape(3, okeys.size).max(axis=0) > ACTIVE_DUAL]
        self.cache[signature] = (solution, active, held)
        return SOLVED, solution, active, held

    def _solve_blocks(self, members: IntArray, keys: Keys, boxes: BoxMask, lin: Trajectories
                      ) -> tuple[Trajectories, Keys] | None:
        """One Gauss-Seidel sweep over spatial blocks of a large group: each block's QP holds
        the vehicles outside it at their latest values (its rows to them one-sided). Every
        row ends up enforced against the final values of both vehicles (a row across two
        blocks is enforced when the later block is solved), so the result satisfies all of
        the group's rows and boxes; it is a feasible point of the group's QP, not
        necessarily its optimum. None when some block's QP fails (the caller then solves
        the group whole)."""
        scenario = self.scenario
        dt = scenario.dt
        m = len(members)
        pairs = self.codec.decode(keys)
        u = directions(lin[0], scenario.separation_scale, pairs, self.continuous,
                       scenario.min_separation, _moving(scenario))
        coef = u / scenario.separation_scale
        local = np.full(self.codec.n, -1, dtype=np.intp)
        local[members] = np.arange(m)
        li, lj = local[pairs.i], local[pairs.j]
        kinds = (0, 1, 2) if self.continuous else (0,)
        count = len(pairs)
        kind = np.repeat(np.array(kinds, dtype=np.intp), count)
        ri, rj = np.tile(li, len(kinds)), np.tile(lj, len(kinds))
        rk = np.tile(pairs.k, len(kinds))
        rcoef = np.tile(coef, (len(kinds), 1))
        p, v, a = (x[members].copy() for x in lin)
        active = np.zeros(count, dtype=bool)

        for block in _spatial_blocks(lin[0][members].mean(axis=1), self.block_size):
            inside = np.zeros(m, dtype=bool)
            inside[block] = True
            sub = np.full(m, -1, dtype=np.intp)
            sub[block] = np.arange(len(block))
            in_i, in_j = inside[ri], inside[rj]
            take = in_i | in_j
            kind_sel, k_sel = kind[take], rk[take]
            i_sel, j_sel, c_sel = ri[take], rj[take], rcoef[take]
            first_in = in_i[take]
            # The inside vehicle becomes i; a row whose i is outside flips its sign.
            own = np.where(first_in, i_sel, j_sel)
            other = np.where(first_in, j_sel, i_sel)
            both = first_in & in_j[take]
            c_own = np.where(first_in[:, None], c_sel, -c_sel)
            at = np.where(kind_sel == 2, k_sel + 1, k_sel)
            point = p[other, at] + np.where((kind_sel == 1)[:, None],
                                            0.5 * dt * v[other, k_sel], 0.0)
            offset = np.where(both, 0.0, np.einsum("rc,rc->r", c_own, point))
            rows = SeparationRows(
                i=sub[own], j=np.where(both, sub[other], -1), k=k_sel, kind=kind_sel,
                coef=c_own, offset=offset,
            )
            vehicles = members[block]
            qp = build_group_qp(scenario, vehicles, rows, boxes.take(vehicles))
            self.solves += 1
            result = self.solver.solve(qp)
            if result.status != SOLVED or result.x is None:
                return None
            p[block], v[block], a[block] = StageLayout(scenario.steps, len(block)).unpack(
                result.x)
            if result.separation_duals is not None and len(rows):
                hit = np.flatnonzero(take)[result.separation_duals > ACTIVE_DUAL] % count
                active[hit] = True
        return (p, v, a), keys[active]


def _moving(scenario: Scenario) -> bool:
    """Does some vehicle start moving (first intervals linearised along their chords)?"""
    return scenario.start_velocities is not None


def _spatial_blocks(points: FloatArray, size: int) -> list[IntArray]:
    """Indices of `points` in blocks of at most `size`, by recursive bisection along the
    widest axis (nearby vehicles, which share most rows, land in the same block)."""
    out: list[IntArray] = []
    stack = [np.arange(len(points))]
    while stack:
        part = stack.pop()
        if len(part) <= size:
            out.append(part)
            continue
        axis = int(np.argmax(np.ptp(points[part], axis=0)))
        order = part[np.argsort(points[part, axis], kind="stable")]
        half = len(order) // 2
        stack += [order[half:], order[:half]]
    return out


def _keep_right_bend(positions: FloatArray, scenario: Scenario, amplitude: float) -> FloatArray:
    """Every path bent sideways to the right of its vehicle's travel by up to `amplitude`
    (a sine bump, zero at start and goal), as the first linearisation point."""
    travel = scenario.goals - scenario.starts
    right = np.stack([travel[:, 1], -travel[:, 0], np.zeros(len(travel))], axis=1)
    norm = np.linalg.norm(right, axis=1, keepdims=True)
    right = np.where(norm > 1e-9, right / np.where(norm > 1e-9, norm, 1.0), 0.0)
    bump = np.sin(np.pi * np.linspace(0.0, 1.0, positions.shape[1]))
    return positions + amplitude * bump[None, :, None] * right[:, None, :]


def _groups(keys: Keys, codec: _Codec, forced: IntArray) -> list[tuple[IntArray, Keys]]:
    """Connected components of the vehicles linked by rows, each with its sorted keys, plus
    a group of its own for every `forced` vehicle (a box broke) that has no rows."""
    if keys.size == 0:  # no links (often so in prioritized batches): each vehicle alone
        return [(np.array([f], dtype=np.intp), keys) for f in np.unique(forced)]
    pairs = codec.decode(keys)
    n = codec.n
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs.i, pairs.j)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    involved = np.union1d(np.concatenate([pairs.i, pairs.j]), forced).astype(np.intp)
    row_label = label[pairs.i]
    order = np.argsort(row_label, kind="stable")
    sorted_labels = row_label[order]
    out = []
    for lab in np.unique(label[involved]):
        lo, hi = np.searchsorted(sorted_labels, [lab, lab + 1])
        members = involved[label[involved] == lab]
        out.append((members, np.sort(keys[order[lo:hi]])))
    return out


def _expand(pairs: PairSteps, last: int) -> PairSteps:
    """Pair-steps plus their neighbours k-1 and k+1 (within 0..last)."""
    parts = []
    for shift in (-1, 0, 1):
        k = pairs.k + shift
        ok = (k >= 0) & (k <= last)
        parts.append(PairSteps(pairs.i[ok], pairs.j[ok], k[ok]))
    return PairSteps.concat(parts)


def _seed_keys(lin: Trajectories, scenario: Scenario, options: ScpOptions,
               codec: _Codec) -> Keys:
    """Rows an iteration starts with (besides those carried over as active): the deepest
    point of every close approach and its neighbours; every row with culling off."""
    lin_positions = lin[0]
    n, stages = lin_positions.shape[0], lin_positions.shape[1]
    count = stages - 1 if options.continuous else stages
    if not options.culling:
        i, j = all_pairs(n)
        k = np.tile(np.arange(count, dtype=np.intp), len(i))
        return codec.encode(PairSteps(np.repeat(i, count), np.repeat(j, count), k))
    below = scenario.min_separation * (1.0 + options.candidate_margin)
    if n >= NEAR_MIN_VEHICLES:  # only the intervals of the windows where a pair is near
        near = near_windows(*lin, scenario.dt, scenario.separation_scale, below, MARGIN_WINDOW)
        pairs, distance = close_among(
            lin_positions, scenario.separation_scale, below, options.continuous,
            window_rows(near, MARGIN_WINDOW, options.continuous, stages - 1))
    else:
        pairs, distance = close_rows(lin_positions, scenario.separation_scale, below,
                                     options.continuous)
    return np.unique(codec.encode(_expand(worst_per_run(pairs, distance), count - 1)))


@dataclass(frozen=True)
class _Pruning:
    """What the all-pairs row check knows at `lin` (see `_margins`): a row set can be broken
    only where its value at `lin` exceeds R by less than its two vehicles have moved."""

    near_i: IntArray
    near_j: IntArray
    near: FloatArray
    """(near pairs, K or K+1): each interval's (step's) smallest row value at `lin` - R
    (or (near pairs, 1): one bound for all of a pair's intervals)."""
    far: FloatArray | None
    """Per pair (all_pairs order), a lower bound on its smallest row value at `lin` - R,
    +inf for the near pairs; None when every pair is near."""


def _margins(scenario: Scenario, options: ScpOptions, lin: Trajectories) -> _Pruning:
    """Exact interval margins for every pair in small fleets; in large ones, for the pairs
    and time windows the broad phase finds near, and `far_margin_bound` elsewhere."""
    n, scale, separation = len(lin[0]), scenario.separation_scale, scenario.min_separation
    pair_i, pair_j = all_pairs(n)
    if n < NEAR_MIN_VEHICLES:
        return _Pruning(pair_i, pair_j, interval_margins(
            lin[0], lin[1], scenario.dt, scale, options.continuous, separation,
            moving=_moving(scenario)) - separation, None)
    half_speed, step = far_margin_bound(lin[0], lin[1], scenario.dt, scale)
    own = half_speed + step
    # Far pairs get a margin of at least FAR_SLACK * R: they are checked only once their
    # vehicles have moved that far from `lin` in total.
    reach = separation * (1.0 + FAR_SLACK) + 2.0 * float(own.max())
    near = near_windows(*lin, scenario.dt, scale, reach, MARGIN_WINDOW)
    keys = np.unique(near.i.astype(np.int64) * n + near.j)
    near_i, near_j = (keys // n).astype(np.intp), (keys % n).astype(np.intp)
    far = reach - separation - own[pair_i] - own[pair_j]
    far[pair_index(near_i, near_j, n)] = np.inf
    # A near pair's intervals outside its near windows keep the far bound.
    count = lin[0].shape[1] - 1 if options.continuous else lin[0].shape[1]
    margin = np.repeat((reach - separation - own[near_i] - own[near_j])[:, None], count, axis=1)
    rows = window_rows(near, MARGIN_WINDOW, options.continuous, lin[0].shape[1] - 1)
    at = np.searchsorted(keys, rows.i.astype(np.int64) * n + rows.j)
    margin[at, rows.k] = values_among(
        lin[0], lin[0], lin[1], scenario.dt, scale, separation, options.continuous, rows,
        _moving(scenario)) - separation
    return _Pruning(near_i, near_j, margin, far)


def _suspects(pruning: _Pruning, moved: FloatArray, tolerance: float) -> PairSteps:
    """The near pairs' intervals (steps) that may be broken after the vehicles moved by
    `moved` (`row_displacements`) from `lin`, in pair chunks that bound memory."""
    per = max(1, CHUNK // moved.shape[1])
    parts = []
    for lo in range(0, len(pruning.near_i), per):
        i, j = pruning.near_i[lo:lo + per], pruning.near_j[lo:lo + per]
        pi, kk = np.nonzero(pruning.near[lo:lo + per] - moved[i] - moved[j] < tolerance)
        parts.append(PairSteps(i[pi], j[pi], kk.astype(np.intp)))
    return PairSteps.concat(parts)


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
    codec: _Codec,
    groups_solver: _GroupSolver,
    lin: Trajectories,
    base: Trajectories,
    keys: Keys,
    boxes: BoxMask,
    okeys: Keys | None = None,
) -> _IterationResult:
    """One SCP iteration: solve, check every row and box, add what is broken, repeat.
    okeys: the obstacle rows it starts with (with obstacles)."""
    tolerance = options.violation_tolerance
    forced = np.zeros(0, dtype=np.intp)
    obstacles = groups_solver.obstacles
    okeys = np.zeros(0, dtype=np.int64) if okeys is None else okeys
    scale = scenario.separation_scale
    # Rows are only checked where they can be violated: an interval whose rows all hold by
    # `margin` at `lin` stays clear while its two vehicles move less than that in total.
    pair_i, pair_j = all_pairs(codec.n)
    pruning = _margins(scenario, options, lin)
    while True:
        p, v, a = (x.copy() for x in base)
        owners = obstacles.vehicles_of(okeys) if obstacles is not None else forced
        groups = _groups(keys, codec, np.union1d(forced, owners).astype(np.intp))
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
        # Every violated row goes in at once: fewer rounds than adding the worst of each
        # run (measured on the paper and scale cases), at a similar QP size.
        moved = row_displacements(lin[:2], (p, v), scenario.dt, scale, options.continuous)
        violated, _ = violated_among(
            lin[0], p, v, scenario.dt, scale, scenario.min_separation, tolerance,
            options.continuous, _suspects(pruning, moved, tolerance), _moving(scenario),
        )
        if pruning.far is not None:
            most = moved.max(axis=1)
            far = np.flatnonzero(pruning.far - most[pair_i] - most[pair_j] < tolerance)
            if far.size:  # pairs the broad phase left out, whose vehicles moved far
                beyond, _ = violated_among(
                    lin[0], p, v, scenario.dt, scale, scenario.min_separation, tolerance,
                    options.continuous, _suspects(_Pruning(
                        pair_i[far], pair_j[far], pruning.far[far, None], None), moved,
                        tolerance), _moving(scenario),
                )
                violated = PairSteps.concat([violated, beyond])
        added = np.setdiff1d(codec.encode(violated), keys)
        new_boxes = broken_boxes(scenario, p, v, a, tolerance) - boxes
        o_added = (obstacles.violated(lin[0], p, v, okeys, tolerance) if obstacles is not None
                   else okeys[:0])
        if added.size == 0 and not new_boxes.any() and o_added.size == 0:
            all_active = np.concatenate(active) if active else keys[:0]
            all_held = np.concatenate(held) if held else okeys[:0]
            largest = max((len(m) for m, _ in groups), default=0)
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


def run_scp(
    scenario: Scenario,
    solver: QPSolver,
    options: ScpOptions | None = None,
    progress: Callable[[IterationRecord], None] | None = None,
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
    reachable (`planner.spacetime`): no route seeding of its own.
    """
    options = options or ScpOptions()
    first, first_seconds = first_qp or timed_first_qp(scenario, solver)
    base = (first.positions, first.velocities, first.accelerations)
    if first.status != SOLVED:
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
            positions=base[0], velocities=base[1], accelerations=base[2],
            iterations=[], first_qp_seconds=first_seconds,
            infeasible_groups=(group,),
        )

    history: list[IterationRecord] = []

    def record(rec: IterationRecord) -> None:
        history.append(rec)
        if progress is not None:
            progress(rec)

    cost = thrust_cost(first.accelerations)
    record(IterationRecord(0, cost, None, 0, first.qp_solves, 0, first_seconds))

    codec = _Codec(len(scenario.vehicles), scenario.steps)
    dual = options.dual and solver.name == "piqp" and scenario.steps <= DUAL_MAX_STEPS
    groups_solver = _GroupSolver(scenario, solver, codec, options.continuous,
                                 options.split_above, options.block_size, dual)
    current = base if guess is None else guess
    obstacle_rows = None
    if scenario.obstacles and not routed:  # routes, or the verdict on an unreachable goal
        seeded = seed_routes(scenario, current)
        if seeded.unreachable is not None:
            return ScpOutcome(
                status=PlanStatus.INFEASIBLE, message=seeded.unreachable,
                positions=base[0], velocities=base[1], accelerations=base[2],
                iterations=history, first_qp_seconds=first_seconds,
                infeasible_groups=("obstacles",),
            )
        current = seeded.guess
    if scenario.obstacles or scenario.fixed:
        obstacle_rows = groups_solver.obstacles = OneSidedRows(scenario, options.obstacle_seed)
    carried = np.zeros(0, dtype=np.int64)
    held = np.zeros(0, dtype=np.int64)
    retried = 0
    last: _IterationResult | None = None
    status, message = PlanStatus.MAX_ITERATIONS, ""
    for iteration in range(1, scenario.max_iterations + 1):
        t0 = time.perf_counter()
        solves_before = groups_solver.solves
        keys = np.union1d(_seed_keys(current, scenario, options, codec), carried)
        okeys = (None if obstacle_rows is None
                 else np.union1d(obstacle_rows.seed(current), held))
        groups_solver.cache.clear()
        last = _solve_iteration(
            scenario, options, codec, groups_solver, current, base, keys,
            near_boxes(scenario, *current, dual=dual), okeys,
        )
        if last.status != SOLVED:
            # Degenerate crossings (vehicles of a symmetric swap all meeting at one point)
            # can leave the linearised QP empty. Linearise once more about paths bent to
            # the right of each vehicle's travel, which turns such a meeting into a
            # roundabout; any linearisation point gives valid (inner) rows.
            bent = (_keep_right_bend(current[0], scenario,
                                     BEND_AMPLITUDE * scenario.min_separation),
                    current[1], current[2])
            groups_solver.cache.clear()
            keys = np.union1d(_seed_keys(bent, scenario, options, codec), carried)
            okeys = (None if obstacle_rows is None
                     else np.union1d(obstacle_rows.seed(bent), held))
            last = _solve_iteration(
                scenario, options, codec, groups_solver, bent, base, keys,
                near_boxes(scenario, *current, dual=dual), okeys,
            )
            retried += 1
        if last.status != SOLVED:
            ids = [scenario.vehicles[i].id for i in last.failed]
            return ScpOutcome(
                status=PlanStatus.INFEASIBLE,
                message=(
                    f"iteration {iteration}: the QP of vehicles {', '.join(ids)} has no "
                    f"solution with the linearised separation"
                    f"{'' if obstacle_rows is None else ' and obstacle'} rows "
                    f"(solver: {last.status})"
                ),
                positions=current[0], velocities=current[1], accelerations=current[2],
                iterations=history, first_qp_seconds=first_seconds,
                infeasible_groups=("separation",) if obstacle_rows is None
                else ("separation", "obstacles"),
            )
        new_cost = thrust_cost(last.solution[2])
        change = abs(new_cost - cost)
        rows_per_key = 3 if options.continuous else 1
        record(IterationRecord(
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
    return ScpOutcome(
        status=status, message=message,
        positions=current[0], velocities=current[1], accelerations=current[2],
        iterations=history, first_qp_seconds=first_seconds,
    )
