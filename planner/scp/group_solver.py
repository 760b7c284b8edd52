"""One SCP iteration's QPs, a group of vehicles linked by rows at a time (`planner.scp.loop`).

`GroupSolver` builds a group's QP from its separation, one-sided and box rows and solves it
through its dual (`planner.scp.dual`) or as the primal staged QP (`planner.scp.qp`), remembering
solutions by (members, constraints) so a re-solve touches only the groups that changed.
`groups_of` finds the groups: the connected components of the vehicles linked by rows.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from planner.model.scenario import Scenario
from planner.scp.dual import ActiveRows, FleetMoves, solve_group_dual
from planner.scp.obstacle_rows import concat_rows
from planner.scp.one_sided import OneSidedRows
from planner.scp.qp import BoxMask, SeparationRows, StageLayout, build_group_qp
from planner.scp.separation import PairSteps, directions
from planner.scp.solvers import SOLVED, QPSolver
from planner.types import FloatArray, IntArray

__all__ = ["ACTIVE_DUAL", "Codec", "GroupSolver", "Keys", "Trajectories", "groups_of",
           "spatial_blocks", "starts_moving"]

Keys = NDArray[np.int64]
Trajectories = tuple[FloatArray, FloatArray, FloatArray]

#: A separation row whose multiplier exceeds this is active and is carried to the next
#: iteration (re-linearised there): active sets change little between SCP iterations.
ACTIVE_DUAL = 1e-7


class Codec:
    """Encodes (i, j, k) pair-steps as int64 keys for fast set arithmetic."""

    def __init__(self, vehicles: int, steps: int) -> None:
        self.n = vehicles
        self.stages = steps + 1

    def encode(self, pairs: PairSteps) -> Keys:
        return pairs.keys(self.n, self.stages)

    def decode(self, keys: Keys) -> PairSteps:
        return PairSteps.from_keys(keys, self.n, self.stages)


def starts_moving(scenario: Scenario) -> bool:
    """Does some vehicle start moving (first intervals linearised along their chords)?"""
    return scenario.start_velocities is not None


class GroupSolver:
    """Builds and solves one group's QP; caches solutions by (members, constraints) so a
    re-solve only touches the groups whose constraints changed."""

    def __init__(self, scenario: Scenario, solver: QPSolver, codec: Codec, continuous: bool,
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
        obstacle_keys: the group's obstacle rows (`planner.scp.obstacle_rows`).
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
                           scenario.min_separation, starts_moving(scenario))
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
        if self.dual:
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
                       scenario.min_separation, starts_moving(scenario))
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

        for block in spatial_blocks(lin[0][members].mean(axis=1), self.block_size):
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


def spatial_blocks(points: FloatArray, size: int) -> list[IntArray]:
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


def groups_of(keys: Keys, codec: Codec, forced: IntArray) -> list[tuple[IntArray, Keys]]:
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
