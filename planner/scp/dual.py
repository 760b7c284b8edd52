"""A group's QP solved through its dual: one variable per inequality row instead of nine per
vehicle and step.

Every vehicle and axis has the same equality-constrained problem (double integrator from rest
to rest, a[K-1] = 0, cost sum a^2; the gravity term is constant on the feasible set), whose
optimum x* is the straight synchronised move (`planner.scp.first_qp.straight_moves`). Every row
of the group's QP, a separation row c'(g_i - g_j) >= R or a box l <= g <= u, is a linear
functional g of one or two vehicles' trajectories (position, velocity, Bernstein middle
point, acceleration or jerk at a step). With M the inverse Hessian on the feasible set
(one K x K matrix for every vehicle and axis), the QP's dual is

    min_{lambda >= 0}  1/2 lambda' Q lambda + (C x* - h)' lambda,   Q = C M C',

and its solution gives the QP's own: x = x* + M C' lambda (exact; the same optimum, and the
same multipliers, as the primal QP). Q[r, s] = (c_r . c_s) sum over shared vehicles of
sign_r sign_s W[f_r, f_s], W = T M T' the "compliance" between two functionals (one
(F x F) matrix per (K, dt), F ~ 5K). Q has one row per constraint and couples only rows
that share a vehicle, so it is small and sparse where the primal KKT system has ~15 rows per
vehicle and step (measured in the README, Drone-show scale). Where every vehicle meets
dozens of others the rows sharing vehicles couple nearly all of Q; the working set keeps
each solve to about one row per close approach (`GroupDual.worst_per_link`), so Q's blocks stay
small there too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from planner.model.scenario import Scenario
from planner.scp.active_rows import ActiveRows
from planner.scp.first_qp import straight_moves_of
from planner.scp.functionals import Functionals, functionals
from planner.scp.qp import A, BoxMask, P, SeparationRows, V
from planner.scp.solvers import FAILED, INFEASIBLE, MAX_ITER, SOLVED
from planner.types import FloatArray, IntArray

__all__ = ["ActiveRows", "DualOutcome", "FleetMoves", "GroupDual", "solve_group_dual"]

Keys = NDArray[np.int64]


#: Largest block of the dual matrix (entries of Q before fill-in) worth building; beyond it
#: (a vehicle with thousands of box rows, a giant crowd's every row) the primal QP is the
#: better tool. Working sets below it still solve a group whose whole Q is larger.
MAX_PAIRS = 2_000_000
#: `GroupDual.solve`'s status when the rows it would need exceed MAX_PAIRS.
TOO_LARGE = "too_large"


@dataclass(frozen=True)
class DualOutcome:
    status: str
    solution: tuple[FloatArray, FloatArray, FloatArray] | None
    separation_duals: FloatArray | None
    """Multipliers of the separation rows, in the order given."""
    iterations: int


def _box_rows(scenario: Scenario, fn: Functionals, boxes: BoxMask, members: IntArray
              ) -> tuple[IntArray, IntArray, IntArray, FloatArray, FloatArray]:
    """One-sided rows (vehicle, functional, axis, sign, rhs) for every finite side of every
    box in the mask: sign * g >= rhs. The jerk functional takes a[-1] = 0, so the first
    step's jerk box is shifted by each vehicle's acceleration before the start."""
    lim = scenario.limits
    inf3 = np.full(3, np.inf)
    vmax = inf3 if lim.velocity_max is None else lim.velocity_max
    amax = inf3 if lim.acceleration_max is None else lim.acceleration_max
    jmax = inf3 if lim.jerk_max is None else lim.jerk_max * scenario.dt
    parts = []
    for var, where, lo, hi in (
        (P, fn.position, lim.position_min, lim.position_max),
        (V, fn.velocity, -vmax, vmax),
        (A, fn.acceleration, -amax, amax),
    ):
        veh, k, axis = np.nonzero(boxes.bounds[:, :, var, :])
        parts.append((veh, where(k), axis, lo[axis], hi[axis]))
    if lim.jerk_max is not None:
        veh, k, axis = np.nonzero(boxes.jerk)
        before = np.where(k == 0, scenario.initial_accelerations[members][veh, axis], 0.0)
        parts.append((veh, fn.jerk(k), axis, before - jmax[axis], before + jmax[axis]))
    veh, k, axis = np.nonzero(boxes.wall)
    parts.append((veh, fn.middle(k), axis, lim.position_min[axis], lim.position_max[axis]))
    veh = np.concatenate([x[0] for x in parts])
    func = np.concatenate([x[1] for x in parts])
    axis = np.concatenate([x[2] for x in parts])
    lo = np.concatenate([x[3] for x in parts])
    hi = np.concatenate([x[4] for x in parts])
    low_ok, high_ok = np.isfinite(lo), np.isfinite(hi)
    return (np.concatenate([veh[low_ok], veh[high_ok]]),
            np.concatenate([func[low_ok], func[high_ok]]),
            np.concatenate([axis[low_ok], axis[high_ok]]),
            np.concatenate([np.ones(int(low_ok.sum())), -np.ones(int(high_ok.sum()))]),
            np.concatenate([lo[low_ok], -hi[high_ok]]))


#: Multipliers above this count as active for `ActiveRows` (interior-point solutions leave
#: tiny positive values on inactive rows).
ACTIVE = 1e-7
#: Rounds of the working-set method before it solves every row at once.
WORKING_SET_ROUNDS = 8
#: A working set of more than this fraction of the rows is solved as the whole dual.
WORKING_SET_FRACTION = 0.5
#: The working set's solves ask PIQP for this fraction of the check's tolerance: the nearly
#: parallel rows of one close approach split their multipliers as the primal does at a
#: thousandth (random16, `tests/planner/test_dual.py`; 2e-6 apart at a tenth).
SOLVE_TOLERANCE = 1e-3


def _solve_bounded(Q: sp.csc_matrix, c: FloatArray, tolerance: float
                   ) -> tuple[str, FloatArray | None, int]:
    """min 1/2 l'Ql + c'l, l >= 0 (Q: upper triangle) with PIQP: (status, l, iterations)."""
    import piqp

    n = len(c)
    solver = piqp.SparseSolver()
    s = solver.settings
    s.eps_abs = tolerance
    s.eps_rel = tolerance * 1e-1
    s.max_iter = 200
    solver.setup(Q, c, None, None, None, None, None, np.zeros(n), np.full(n, np.inf))
    status = solver.solve()
    iterations = int(solver.result.info.iter)
    if status != piqp.PIQP_SOLVED:
        # The dual (bounds only) is always feasible; unbounded: the QP is infeasible.
        name = (INFEASIBLE if status in (piqp.PIQP_PRIMAL_INFEASIBLE, piqp.PIQP_DUAL_INFEASIBLE)
                else MAX_ITER if status == piqp.PIQP_MAX_ITER_REACHED else FAILED)
        return name, None, iterations
    return SOLVED, np.maximum(np.array(solver.result.x), 0.0), iterations


class GroupDual:
    """One group's dual: its rows as entries (row, vehicle, functional, coefficient vector;
    a separation row has one entry per vehicle it moves, a box row one) and the linear term
    c = C x* - h. Blocks of Q = C M C' are built for the rows a solve needs, and the
    gradient Q l + c (every row's slack at the trajectories l gives) through the forces on
    the functionals, so that a solve over a few rows never builds all of Q."""

    def __init__(self, fn: Functionals, vehicles: int, e_row: IntArray, e_veh: IntArray,
                 e_func: IntArray, e_coef: FloatArray, c: FloatArray) -> None:
        self.fn, self.m = fn, vehicles
        self.e_row, self.e_veh, self.e_func, self.e_coef = e_row, e_veh, e_func, e_coef
        self.c = c
        order = np.argsort(e_row, kind="stable")
        self._by_row = order
        self._row_start = np.searchsorted(e_row[order], np.arange(len(c) + 1))
        # Per row its link: (lowest vehicle, highest vehicle) of its entries.
        low = np.full(len(c), vehicles, dtype=np.int64)
        high = np.full(len(c), -1, dtype=np.int64)
        np.minimum.at(low, e_row, e_veh)
        np.maximum.at(high, e_row, e_veh)
        self._links = low * (vehicles + 1) + high

    def block(self, rows: IntArray) -> sp.csc_matrix:
        """Q restricted to `rows` (sorted), upper triangle, in their order: every pair of
        their entries on the same vehicle."""
        take = self._entries_of(rows)
        local = np.searchsorted(rows, self.e_row[take])
        veh = self.e_veh[take]
        count = np.bincount(veh, minlength=self.m)
        order = np.argsort(veh, kind="stable")
        first = np.concatenate([[0], np.cumsum(count)[:-1]])
        reps = count[veh[order]]
        left = np.repeat(np.arange(len(order)), reps)
        block_start = np.repeat(np.cumsum(reps) - reps, reps)
        right = first[veh[order][left]] + (np.arange(len(left)) - block_start)
        left, right = order[left], order[right]
        keep = local[left] <= local[right]
        left, right = left[keep], right[keep]
        el, er = take[left], take[right]
        values = (np.einsum("ec,ec->e", self.e_coef[el], self.e_coef[er])
                  * self.fn.compliance[self.e_func[el], self.e_func[er]])
        return sp.csc_matrix((values, (local[left], local[right])),
                             shape=(len(rows), len(rows)))

    def _entries_of(self, rows: IntArray) -> IntArray:
        """Indices of the entries of `rows`."""
        lo, hi = self._row_start[rows], self._row_start[rows + 1]
        size = hi - lo
        offset = np.repeat(lo - np.cumsum(size) + size, size)
        entries: IntArray = self._by_row[np.arange(int(size.sum())) + offset]
        return entries

    def moves(self, lam: FloatArray) -> FloatArray:
        """(m, 3, F): every functional's change from x* under the multipliers `lam`,
        M C' lam read through the functionals (only rows with a multiplier push)."""
        fn, m = self.fn, self.m
        count = fn.compliance.shape[0]
        pushing = np.flatnonzero(lam[self.e_row] > 0.0)
        push = lam[self.e_row[pushing], None] * self.e_coef[pushing]
        force = sp.csr_matrix(
            (push.reshape(-1), ((self.e_veh[pushing, None] * 3 + np.arange(3)).reshape(-1),
                                np.repeat(self.e_func[pushing], 3))),
            shape=(3 * m, count))
        return np.asarray(force @ fn.compliance).reshape(m, 3, count)

    def gradient(self, moves: FloatArray) -> FloatArray:
        """Q l + c from `moves(l)`: each row's slack at the trajectories of l."""
        along = np.einsum("ec,ec->e", self.e_coef, moves[self.e_veh, :, self.e_func])
        return self.c + np.bincount(self.e_row, along, minlength=len(self.c))

    def worst_per_link(self, broken: NDArray[np.bool_], gradient: FloatArray
                        ) -> NDArray[np.bool_]:
        """Of the `broken` rows, the most broken of each link (the rows that move the same
        vehicle or pair of vehicles): a close approach breaks a run of neighbouring rows of
        which one or two end up active, and the rest then hold."""
        link = self._links
        rows = np.flatnonzero(broken)
        order = rows[np.lexsort((gradient[rows], link[rows]))]
        first = np.ones(len(order), dtype=bool)
        first[1:] = link[order][1:] != link[order][:-1]
        out = np.zeros_like(broken)
        out[order[first]] = True
        return out

    def pairs(self, rows: IntArray) -> int:
        """Entries of Q's block of `rows`: per vehicle, the square of its entries."""
        per_vehicle = np.bincount(self.e_veh[self._entries_of(rows)], minlength=self.m)
        return int(np.sum(per_vehicle.astype(np.int64) ** 2))

    def solve(self, start: NDArray[np.bool_], tolerance: float
              ) -> tuple[str, FloatArray | None, FloatArray | None, int]:
        """min 1/2 l'Ql + c'l, l >= 0, over a working set of rows from `start` (rows
        believed active): the multipliers of the other rows held at 0, which is optimal for
        the whole dual exactly when every other row's gradient (its slack in the group's
        QP) is >= -tolerance; of the rows that break that, the most broken of each link
        joins the set (`worst_per_link`) and it is solved again.
        The same optimum as one solve of every row, in smaller solves (about a tenth of the
        rows are active), and a set started from the rows active in an earlier, similar QP
        usually needs one or two. Every row at once after WORKING_SET_ROUNDS rounds or once
        the set holds WORKING_SET_FRACTION of the rows. Status TOO_LARGE when a block to
        solve exceeds MAX_PAIRS entries. Returns (status, l, `moves(l)`, PIQP iterations)."""
        n = len(self.c)
        whole = np.arange(n)
        fits = self.pairs(whole) <= MAX_PAIRS
        work = start.copy()
        iterations = 0
        for _ in range(WORKING_SET_ROUNDS):
            if fits and work.sum() > WORKING_SET_FRACTION * n:
                break
            idx = np.flatnonzero(work)
            if not fits and self.pairs(idx) > MAX_PAIRS:
                return TOO_LARGE, None, None, iterations
            lam = np.zeros(n)
            if idx.size:
                status, sub, its = _solve_bounded(self.block(idx), self.c[idx],
                                                  SOLVE_TOLERANCE * tolerance)
                iterations += its
                if sub is None:
                    return status, None, None, iterations
                lam[idx] = sub
            moves = self.moves(lam)
            gradient = self.gradient(moves)
            broken = ~work & (gradient < -tolerance)
            if not broken.any():
                return SOLVED, lam, moves, iterations
            work |= self.worst_per_link(broken, gradient)
        if not fits:
            return TOO_LARGE, None, None, iterations
        status, lam_all, its = _solve_bounded(self.block(whole), self.c,
                                              SOLVE_TOLERANCE * tolerance)
        if lam_all is None:
            return status, None, None, iterations + its
        return status, lam_all, self.moves(lam_all), iterations + its


class FleetMoves:
    """Every vehicle's straight move (`planner.scp.first_qp.straight_moves`) and the values of
    its functionals, computed once for the many group solves of one scenario."""

    def __init__(self, scenario: Scenario) -> None:
        fn = functionals(scenario.steps, scenario.dt)
        self.moves = straight_moves_of(scenario, np.arange(len(scenario.vehicles)))
        self.values = fn.values(*self.moves, scenario.dt)

    def of(self, members: IntArray) -> tuple[tuple[FloatArray, FloatArray, FloatArray],
                                             FloatArray]:
        """((p, v, a), functional values) of the vehicles `members`."""
        p, v, a = self.moves
        return (p[members], v[members], a[members]), self.values[members]


def solve_group_dual(scenario: Scenario, members: IntArray, rows: SeparationRows,
                     boxes: BoxMask, tolerance: float = 1e-8, row_ids: Keys | None = None,
                     memory: ActiveRows | None = None, fleet: FleetMoves | None = None
                     ) -> DualOutcome | None:
    """The group QP of `build_group_qp(scenario, members, rows, boxes)`, solved through
    its dual. Returns the group's (p, v, a) and the separation rows' multipliers, or None
    when a block of the dual's matrix to solve would exceed `MAX_PAIRS` entries (the caller
    solves the primal).

    The dual is solved over a working set of rows (`GroupDual.solve`) that starts from the rows
    the straight moves break or, with row_ids and memory (names of the separation rows,
    unique and stable across solves, and what earlier solves found active), from the
    remembered active rows; the memory learns this solve's active rows. fleet: the
    scenario's straight moves, computed once (else this group's are computed here)."""
    dt, steps = scenario.dt, scenario.steps
    fn = functionals(steps, dt)
    m = len(members)
    if fleet is None:
        base = straight_moves_of(scenario, members)
        g_star = fn.values(*base, dt)
    else:
        base, g_star = fleet.of(members)

    # Entries: (row, vehicle, functional, coefficient vector); a row has one or two.
    n_sep = len(rows)
    f_sep = np.where(rows.kind == 0, fn.position(rows.k),
                     np.where(rows.kind == 1, fn.middle(rows.k), fn.position(rows.k + 1)))
    b_veh, b_func, b_axis, b_sign, b_rhs = _box_rows(scenario, fn, boxes, members)
    n_box = len(b_veh)
    n_rows = n_sep + n_box
    box_coef = np.zeros((n_box, 3))
    box_coef[np.arange(n_box), b_axis] = b_sign
    sep_ids = np.arange(n_sep)
    two = rows.j >= 0  # one-sided rows (j = -1) hold the other vehicle fixed
    e_row = np.concatenate([sep_ids, sep_ids[two], n_sep + np.arange(n_box)])
    e_veh = np.concatenate([rows.i, rows.j[two], b_veh])
    e_func = np.concatenate([f_sep, f_sep[two], b_func])
    e_coef = np.concatenate([rows.coef, -rows.coef[two], box_coef])
    sep_rhs = np.full(n_sep, scenario.min_separation)
    if rows.offset is not None:
        sep_rhs = sep_rhs + rows.offset
    rhs = np.concatenate([sep_rhs, b_rhs])

    if n_rows == 0:  # nothing couples or bounds the group: the straight moves
        return DualOutcome(SOLVED, base, np.zeros(0), 0)
    # Linear term: C x* - h (each row's slack at the straight moves).
    c = np.bincount(e_row, np.einsum("ec,ec->e", e_coef, g_star[e_veh, e_func]),
                    minlength=n_rows) - rhs

    dual = GroupDual(fn, m, e_row, e_veh, e_func, e_coef, c)
    box_ids = np.zeros(0, dtype=np.int64)
    # Start from the rows remembered active, else from those the straight moves break.
    start = dual.worst_per_link(c < -tolerance, c)
    if memory is not None and row_ids is not None:
        side = (b_sign > 0).astype(np.int64)
        box_ids = ((members[b_veh].astype(np.int64) * fn.compliance.shape[0] + b_func) * 3
                   + b_axis) * 2 + side
        known = memory.known(row_ids, box_ids)
        if known.any():
            start = known
    status, lam, moves, iterations = dual.solve(start, tolerance)
    if status == TOO_LARGE:
        return None
    if lam is None or moves is None:
        return DualOutcome(status, None, None, iterations)
    if memory is not None and row_ids is not None:
        memory.update(row_ids, lam[:n_sep] > ACTIVE, box_ids, lam[n_sep:] > ACTIVE)

    # x = x* + M C' lambda, read at the functionals p, v, a.
    P_rows = np.arange(steps + 1)
    want = np.concatenate([fn.position(P_rows), fn.velocity(P_rows),
                           fn.acceleration(np.arange(steps))])
    delta = moves[:, :, want].transpose(0, 2, 1)
    p = base[0] + delta[:, :steps + 1]
    v = base[1] + delta[:, steps + 1:2 * (steps + 1)]
    a = base[2] + delta[:, 2 * (steps + 1):]
    return DualOutcome(SOLVED, (p, v, a), lam[:n_sep], iterations)
