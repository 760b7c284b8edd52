"""Sparse QP assembly for a group of vehicles: states and accelerations as variables.

Long: the group QP's variable layout and every part that indexes it: shared structure and rows.

Variables are ordered by time stage so every constraint couples at most two neighbouring
stages (dynamics, jerk, continuous-time separation) or one stage (step separation):
stage k holds, for every vehicle of the group, [p_xyz, v_xyz, a_xyz], i.e.

    index(k, vehicle, var, axis) = k * 9m + vehicle * 9 + var * 3 + axis,   var: 0 p, 1 v, 2 a.

Stage K carries a phantom acceleration a_K (cost weight 1, no constraints) so stages are
uniform; it is zero at the optimum and never reported. The problem is

    min 1/2 x'Px + q'x   s.t.  A x = b,   h_l <= G x <= h_u,   x_l <= x <= x_u,

PIQP's native form; other backends convert. All matrices are built with vectorised COO
arithmetic from one per-vehicle template, never with a Python loop over steps or pairs:
`build_group_qp` takes the equality rows and the cost's Hessian shared by every group of its
shape (`group_structure`) and adds the inequality rows (jerk, walls, separation, each kind by
a function of its own) and the variable bounds.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from planner.model.flatness import GRAVITY
from planner.model.scenario import Scenario
from planner.types import FloatArray, IntArray

__all__ = ["BoxMask", "QuadraticProgram", "SeparationRows", "StageLayout", "build_group_qp",
           "build_structure", "group_structure"]


P, V, A = 0, 1, 2
PER_VEHICLE = 9  # p, v, a, three axes each


@dataclass(frozen=True)
class StageLayout:
    """Where each (stage, vehicle, var, axis) lives in the decision vector of a group."""

    steps: int
    vehicles: int

    @property
    def stage_size(self) -> int:
        return PER_VEHICLE * self.vehicles

    @property
    def size(self) -> int:
        return (self.steps + 1) * self.stage_size

    def index(self, k: IntArray | int, vehicle: IntArray | int, var: int, axis: IntArray | int
              ) -> IntArray:
        index: IntArray = (
            np.asarray(k) * self.stage_size
            + np.asarray(vehicle) * PER_VEHICLE
            + var * 3
            + np.asarray(axis)
        )
        return index

    def unpack(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(positions (m, K+1, 3), velocities (m, K+1, 3), accelerations (m, K, 3))."""
        grid = x.reshape(self.steps + 1, self.vehicles, 3, 3).transpose(1, 0, 2, 3)
        return grid[:, :, P, :], grid[:, :, V, :], grid[:, :-1, A, :]

    def pack(self, p: FloatArray, v: FloatArray, a: FloatArray) -> FloatArray:
        """Inverse of `unpack` (phantom a_K = 0); used for warm starts."""
        m, k1 = p.shape[0], p.shape[1]
        grid = np.zeros((k1, m, 3, 3))
        grid[:, :, P, :] = p.transpose(1, 0, 2)
        grid[:, :, V, :] = v.transpose(1, 0, 2)
        grid[:-1, :, A, :] = a.transpose(1, 0, 2)
        return grid.reshape(-1)


@dataclass(frozen=True)
class SeparationRows:
    """Linearised separation half-spaces c' (x_i - x_j) >= R for a set of pair-instants.

    Each row is given by the two group-local vehicle indices, the stage k, the kind
    (0: position at step k, 1: Bernstein middle point p_k + dt/2 v_k, 2: position at step
    k + 1 with the direction of step k), and `coef` = S n, the scaled unit direction.

    A one-sided row (j = -1, the other vehicle held fixed outside the QP) reads
    coef' x_i >= R + offset, offset = coef' x_other at the row's point.
    """

    i: IntArray
    j: IntArray
    k: IntArray
    kind: IntArray
    coef: FloatArray  # (rows, 3)
    offset: FloatArray | None = None
    """(rows,) right-hand side shifts of one-sided rows (0 for two-sided); None: all 0."""

    def __len__(self) -> int:
        return len(self.i)

    @staticmethod
    def empty() -> SeparationRows:
        z = np.zeros(0, dtype=np.intp)
        return SeparationRows(z, z, z, z, np.zeros((0, 3)))


@dataclass(frozen=True)
class BoxMask:
    """Which box constraints a QP includes (the SCP loop adds the others only if broken).

    bounds: (m, K+1, 3, 3) over (vehicle, stage, var p/v/a, axis): variable bounds on.
    jerk: (m, K, 3) over (vehicle, step, axis): jerk rows on.
    wall: (m, K, 3) over (vehicle, step, axis): rows keeping the Bernstein middle point
      p_k + dt/2 v_k of step k inside the workspace, so that (with p_k and p_k+1 inside)
      the position stays inside over the whole step, not only at the steps.
    """

    bounds: NDArray[np.bool_]
    jerk: NDArray[np.bool_]
    wall: NDArray[np.bool_]

    @staticmethod
    def full(vehicles: int, steps: int) -> BoxMask:
        """Every box: all bounds, jerk rows and wall rows."""
        bounds = np.ones((vehicles, steps + 1, 3, 3), dtype=bool)
        bounds[:, steps, A, :] = False  # the phantom a_K has no bound
        rows = np.ones((vehicles, steps, 3), dtype=bool)
        return BoxMask(bounds, rows, rows.copy())

    def take(self, members: IntArray) -> BoxMask:
        return BoxMask(self.bounds[members], self.jerk[members], self.wall[members])

    def __or__(self, other: BoxMask) -> BoxMask:
        return BoxMask(self.bounds | other.bounds, self.jerk | other.jerk,
                       self.wall | other.wall)

    def __sub__(self, other: BoxMask) -> BoxMask:
        return BoxMask(self.bounds & ~other.bounds, self.jerk & ~other.jerk,
                       self.wall & ~other.wall)

    def any(self) -> bool:
        return bool(self.bounds.any() or self.jerk.any() or self.wall.any())


@dataclass
class QuadraticProgram:
    """min 1/2 x'Px + q'x s.t. Ax = b, h_l <= Gx <= h_u, x_l <= x <= x_u (CSC matrices)."""

    P: sp.csc_matrix
    q: FloatArray
    A: sp.csc_matrix
    b: FloatArray
    G: sp.csc_matrix
    h_l: FloatArray
    h_u: FloatArray
    x_l: FloatArray
    x_u: FloatArray
    constant: float
    """Cost constant so that 1/2 x'Px + q'x + constant is the total-thrust cost."""
    separation_rows: int
    """How many rows at the end of G are separation rows (before them: jerk, wall rows)."""

    @property
    def size(self) -> int:
        return len(self.q)


def _coo(rows: list[IntArray], cols: list[IntArray], vals: list[FloatArray], shape: tuple[int, int]
         ) -> sp.csc_matrix:
    r = np.concatenate(rows) if rows else np.zeros(0, dtype=np.intp)
    c = np.concatenate(cols) if cols else np.zeros(0, dtype=np.intp)
    v = np.concatenate(vals) if vals else np.zeros(0)
    return sp.csc_matrix((v, (r, c)), shape=shape)


#: Groups of at most this many vehicles share their equality and cost matrices between QPs
#: (`group_structure`): prioritized batches build thousands of small QPs of the same shape.
STRUCTURE_CACHE_VEHICLES = 16


def group_structure(steps: int, m: int, dt: float) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """(A_eq, P) of a group of `m` vehicles: the dynamics and boundary-condition rows and
    the cost's Hessian depend only on the shape and dt, so small groups' are built once
    (the solvers only read them)."""
    if m <= STRUCTURE_CACHE_VEHICLES:
        return _cached_structure(steps, m, dt)
    return build_structure(steps, m, dt)


def build_structure(steps: int, m: int, dt: float) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """(A_eq, P) of a group of `m` vehicles built afresh (`group_structure` shares small
    groups' through a cache)."""
    lay = StageLayout(steps, m)
    n = lay.size
    # Grids over (vehicle, axis) and (stage, vehicle, axis): flat index arrays.
    veh = np.repeat(np.arange(m), 3)
    axis = np.tile(np.arange(3), m)
    k_dyn = np.arange(steps)

    # --- equality rows: dynamics (2 K per chain) then boundary conditions (5 per chain).
    grid_k, grid_v = np.meshgrid(k_dyn, np.arange(3 * m), indexing="ij")  # (K, 3m)
    kk, vv = grid_k.ravel(), grid_v.ravel()
    ve, ax = veh[vv], axis[vv]
    n_dyn = kk.size
    row_p = np.arange(n_dyn)
    row_v = n_dyn + np.arange(n_dyn)
    p_k, p_k1 = lay.index(kk, ve, P, ax), lay.index(kk + 1, ve, P, ax)
    v_k, v_k1 = lay.index(kk, ve, V, ax), lay.index(kk + 1, ve, V, ax)
    a_k = lay.index(kk, ve, A, ax)
    ones = np.ones(n_dyn)
    rows = [row_p, row_p, row_p, row_p, row_v, row_v, row_v]
    cols = [p_k1, p_k, v_k, a_k, v_k1, v_k, a_k]
    vals = [ones, -ones, -dt * ones, -0.5 * dt * dt * ones, ones, -ones, -dt * ones]

    chains = np.arange(3 * m)
    cv, ca = veh[chains], axis[chains]
    bc_cols = [
        lay.index(0, cv, P, ca),
        lay.index(0, cv, V, ca),
        lay.index(steps, cv, P, ca),
        lay.index(steps, cv, V, ca),
        lay.index(steps - 1, cv, A, ca),
    ]
    base = 2 * n_dyn
    for idx, col in enumerate(bc_cols):
        rows.append(base + idx * 3 * m + chains)
        cols.append(col)
        vals.append(np.ones(3 * m))
    n_eq = base + 5 * 3 * m
    A_eq = _coo(rows, cols, vals, (n_eq, n))

    # --- cost: sum_k ||a_k + g||^2 = a'a + 2 G a_z + K G^2 per vehicle; phantom a_K weight 1.
    a_mask = np.zeros((steps + 1, m, 3, 3), dtype=bool)
    a_mask[:, :, A, :] = True
    diag = np.where(a_mask.reshape(-1), 2.0, 0.0)
    return A_eq, sp.diags(diag, format="csc")


_cached_structure = functools.lru_cache(maxsize=32)(build_structure)


def build_group_qp(
    scenario: Scenario,
    members: IntArray,
    separation: SeparationRows,
    boxes: BoxMask | None = None,
) -> QuadraticProgram:
    """The QP of the vehicles `members` (scenario indices) with the given separation rows.

    boxes: which variable bounds and jerk rows to include, for the group's vehicles; None:
    all of them. The SCP loop passes only those that can bind and checks the rest.
    """
    dt, steps = scenario.dt, scenario.steps
    m = len(members)
    lay = StageLayout(steps, m)
    n = lay.size
    limits = scenario.limits
    if boxes is None:
        boxes = BoxMask.full(m, steps)

    A_eq, P_mat = group_structure(steps, m, dt)
    starts = scenario.starts[members].reshape(-1)  # chain order: vehicle-major, axis
    goals = scenario.goals[members].reshape(-1)
    start_v = scenario.initial_velocities[members].reshape(-1)
    bc_rhs = [starts, start_v, goals, np.zeros(3 * m), np.zeros(3 * m)]
    n_dyn = steps * 3 * m
    b = np.concatenate([np.zeros(2 * n_dyn), *bc_rhs])

    # --- inequality rows: jerk, then the workspace walls between steps, then separation.
    rows = _Rows()
    if limits.jerk_max is not None:
        _jerk_rows(rows, scenario, members, boxes.jerk, lay)
    if boxes.wall.any():
        _wall_rows(rows, scenario, boxes.wall, lay)
    n_sep = len(separation)
    if n_sep:
        _separation_rows(rows, scenario, separation, lay)
    G = _coo(rows.rows, rows.cols, rows.vals, (rows.count, n))
    h_l = np.concatenate(rows.lower) if rows.lower else np.zeros(0)
    h_u = np.concatenate(rows.upper) if rows.upper else np.zeros(0)
    x_l, x_u = _variable_bounds(scenario, boxes.bounds, m)

    # --- cost: sum_k ||a_k + g||^2 = a'a + 2 G a_z + K G^2 per vehicle; phantom a_K weight 1.
    q = np.zeros((steps + 1, m, 3, 3))
    q[:steps, :, A, 2] = 2.0 * GRAVITY
    constant = steps * m * GRAVITY * GRAVITY

    return QuadraticProgram(
        P=P_mat,
        q=q.reshape(-1),
        A=A_eq,
        b=b,
        G=G,
        h_l=h_l,
        h_u=h_u,
        x_l=x_l,
        x_u=x_u,
        constant=constant,
        separation_rows=n_sep,
    )


@dataclass
class _Rows:
    """A group QP's inequality rows as they are assembled: their COO entries, bounds and
    count (each kind of row is numbered after the ones before it)."""

    rows: list[IntArray] = field(default_factory=list)
    cols: list[IntArray] = field(default_factory=list)
    vals: list[FloatArray] = field(default_factory=list)
    lower: list[FloatArray] = field(default_factory=list)
    upper: list[FloatArray] = field(default_factory=list)
    count: int = 0


def _jerk_rows(rows: _Rows, scenario: Scenario, members: IntArray, mask: NDArray[np.bool_],
               lay: StageLayout) -> None:
    """a_k - a_{k-1} within +-jmax dt where `mask` (vehicle, step, axis) says, a_{-1} the
    acceleration before the start."""
    m = len(members)
    veh, axis = np.repeat(np.arange(m), 3), np.tile(np.arange(3), m)
    j_vehicle, jk, j_axis = np.nonzero(mask)
    jv = j_vehicle * 3 + j_axis
    n_jerk = jk.size
    jrow = rows.count + np.arange(n_jerk)
    rows.rows += [jrow]
    rows.cols += [lay.index(jk, veh[jv], A, axis[jv])]
    rows.vals += [np.ones(n_jerk)]
    later = jk > 0
    rows.rows += [jrow[later]]
    rows.cols += [lay.index(jk[later] - 1, veh[jv[later]], A, axis[jv[later]])]
    rows.vals += [-np.ones(int(later.sum()))]
    assert scenario.limits.jerk_max is not None
    bound = (scenario.limits.jerk_max * scenario.dt)[axis[jv]]
    # the first step's row bounds a_0 alone: shift it by the acceleration before the start
    before = np.where(later, 0.0, scenario.initial_accelerations[members][veh[jv], axis[jv]])
    rows.lower.append(before - bound)
    rows.upper.append(before + bound)
    rows.count += n_jerk


def _wall_rows(rows: _Rows, scenario: Scenario, mask: NDArray[np.bool_],
               lay: StageLayout) -> None:
    """The workspace box at the Bernstein middle point p_k + dt/2 v_k where `mask`
    (vehicle, step, axis) says."""
    limits = scenario.limits
    w_vehicle, wk, w_axis = np.nonzero(mask)
    n_wall = wk.size
    wrow = rows.count + np.arange(n_wall)
    rows.rows += [wrow, wrow]
    rows.cols += [lay.index(wk, w_vehicle, P, w_axis), lay.index(wk, w_vehicle, V, w_axis)]
    rows.vals += [np.ones(n_wall), np.full(n_wall, 0.5 * scenario.dt)]
    rows.lower.append(limits.position_min[w_axis])
    rows.upper.append(limits.position_max[w_axis])
    rows.count += n_wall


def _separation_rows(rows: _Rows, scenario: Scenario, separation: SeparationRows,
                     lay: StageLayout) -> None:
    """c'(p_i - p_j) >= R (+ offset) at a step, its end, or its middle point (`kind`); a
    one-sided row (j < 0) moves vehicle i alone."""
    n_sep = len(separation)
    srow = rows.count + np.arange(n_sep)
    s_k = separation.k
    kind = separation.kind
    stage = np.where(kind == 2, s_k + 1, s_k)
    two = separation.j >= 0
    for c in range(3):
        coef = separation.coef[:, c]
        rows.rows += [srow, srow[two]]
        rows.cols += [lay.index(stage, separation.i, P, c),
                      lay.index(stage[two], separation.j[two], P, c)]
        rows.vals += [coef, -coef[two]]
    mid = kind == 1
    if mid.any():
        mrow = srow[mid]
        mid_two = two[mid]
        for c in range(3):
            coef = 0.5 * scenario.dt * separation.coef[mid, c]
            rows.rows += [mrow, mrow[mid_two]]
            rows.cols += [
                lay.index(s_k[mid], separation.i[mid], V, c),
                lay.index(s_k[mid][mid_two], separation.j[mid][mid_two], V, c),
            ]
            rows.vals += [coef, -coef[mid_two]]
    rhs = np.full(n_sep, scenario.min_separation)
    if separation.offset is not None:
        rhs = rhs + separation.offset
    rows.lower.append(rhs)
    rows.upper.append(np.full(n_sep, np.inf))
    rows.count += n_sep


def _variable_bounds(scenario: Scenario, mask: NDArray[np.bool_], m: int
                     ) -> tuple[FloatArray, FloatArray]:
    """(x_l, x_u): the workspace box on positions, the velocity and acceleration boxes, on
    the variables `mask` (vehicle, stage, kind, axis) keeps; +-inf elsewhere."""
    limits, steps = scenario.limits, scenario.steps
    stage_lo = np.empty((m, 3, 3))
    stage_hi = np.empty((m, 3, 3))
    stage_lo[:, P, :], stage_hi[:, P, :] = limits.position_min, limits.position_max
    inf3 = np.full(3, np.inf)
    vmax = inf3 if limits.velocity_max is None else limits.velocity_max
    amax = inf3 if limits.acceleration_max is None else limits.acceleration_max
    stage_lo[:, V, :], stage_hi[:, V, :] = -vmax, vmax
    stage_lo[:, A, :], stage_hi[:, A, :] = -amax, amax
    x_l = np.tile(stage_lo.reshape(-1), steps + 1)
    x_u = np.tile(stage_hi.reshape(-1), steps + 1)
    off = ~mask.transpose(1, 0, 2, 3).reshape(-1)
    x_l[off] = -np.inf
    x_u[off] = np.inf
    return x_l, x_u
