"""Obstacle rows of the SCP QPs: a separating plane per vehicle, interval and nearby obstacle.

For vehicle i on interval [t_k, t_k+1] and obstacle o, the row is linearised about the
previous iterate (`lin`): q is the point of the chord [p_k, p_k+1] at `lin` nearest to o
(the start for the first interval and the goal for the last, which are fixed and clear),
x the obstacle's point nearest q and n the outward normal there. The plane n'x' = n'x
supports the convex obstacle, so n'p >= n'x + c keeps p at least the clearance c from it.
It is imposed on the three Bernstein control points of the step (p_k, p_k + dt/2 v_k,
p_k+1): the quadratic motion lies in their convex hull, so the clearance holds over the whole
step, exactly for a plane. The rows are one-sided `SeparationRows` (the other side is fixed),
so the primal and the dual group QPs take them unchanged.

Only nearby obstacles get rows: a broad phase (`ObstacleSet.near`, a k-d tree over the
steps' control-point boxes) finds the (vehicle, interval, obstacle) triples that can come
within the clearance; a row is added when the iterate breaks it, like the separation rows
(`planner.scp.lazy_rows`).
"""

from __future__ import annotations

import numpy as np

from planner.model.obstacle_set import ObstacleSet
from planner.model.scenario import Scenario
from planner.scp.golden import golden_minimum
from planner.scp.lazy_rows import LazyRows, Triples, interval_points
from planner.scp.qp import SeparationRows
from planner.types import FloatArray, IntArray

__all__ = ["ObstacleRows", "Triples", "chord_nearest", "concat_rows", "control_points",
           "row_point"]


#: Triples whose row at the linearisation point is within this of binding (in units of the
#: clearance, at least SEED_MIN m) start an iteration's QP.
SEED_FRACTION = 0.5
SEED_MIN = 0.2
#: Golden-section steps locating a chord's point nearest an obstacle (interval shrinks to
#: 0.618^N of the chord).
CHORD_STEPS = 20


def control_points(p: FloatArray, v: FloatArray, dt: float) -> FloatArray:
    """(N, K, 3, 3): per vehicle and interval the Bernstein control points p_k,
    p_k + dt/2 v_k, p_k+1 of the step's quadratic motion."""
    return np.stack([p[:, :-1], p[:, :-1] + 0.5 * dt * v[:, :-1], p[:, 1:]], axis=2)


def chord_nearest(geometry: ObstacleSet, a: FloatArray, b: FloatArray, o: IntArray
                  ) -> FloatArray:
    """The point of each segment [a, b] ((Q, 3) each) nearest obstacle o (Q,): the signed
    distance to a convex set is convex along a segment, so a golden-section search finds it."""
    d = b - a

    def dist(t: FloatArray) -> FloatArray:
        return geometry.signed_distance(a + t[:, None] * d, o)

    t, best_inner = golden_minimum(dist, np.zeros(len(a)), np.ones(len(a)), CHORD_STEPS)
    # The ends can be nearer than the interior search's best (the minimum sits at an end).
    ends = np.stack([np.zeros(len(a)), t, np.ones(len(a))], axis=1)
    values = np.stack([dist(ends[:, 0]), best_inner, dist(ends[:, 2])], axis=1)
    best = ends[np.arange(len(a)), np.argmin(values, axis=1)]
    nearest: FloatArray = a + best[:, None] * d
    return nearest


def row_point(geometry: ObstacleSet, a: FloatArray, b: FloatArray, o: IntArray
              ) -> FloatArray:
    """`chord_nearest` for the rows' linearisation: where obstacle o is a cylinder and the
    chord lies within its height, the chord's point nearest the axis (closed form, exact
    outside the cylinder: the distance there is the horizontal one); the search elsewhere.
    Any point gives a valid supporting plane; this one is the search's up to its tolerance,
    without its 20 distance evaluations (the forest's rows are all such chords)."""
    lo, hi = np.minimum(a[:, 2], b[:, 2]), np.maximum(a[:, 2], b[:, 2])
    upright = ((geometry.circle[o] == 1) & (lo >= geometry.z[o, 0])
               & (hi <= geometry.z[o, 1]))
    if not upright.any():
        return chord_nearest(geometry, a, b, o)
    out = np.empty_like(a)
    d = (b - a)[upright]
    rel = geometry.center[o[upright]] - a[upright, :2]
    across = np.einsum("qc,qc->q", d[:, :2], d[:, :2])
    t = np.clip(np.einsum("qc,qc->q", rel, d[:, :2]) / np.maximum(across, 1e-300), 0.0, 1.0)
    out[upright] = a[upright] + t[:, None] * d
    rest = ~upright
    if rest.any():
        out[rest] = chord_nearest(geometry, a[rest], b[rest], o[rest])
    return out


class ObstacleRows(LazyRows):
    """The obstacle rows of one scenario: planes and the broad phase (`planner.scp.lazy_rows`
    seeds them and checks them lazily)."""

    def __init__(self, scenario: Scenario, seed_fraction: float = SEED_FRACTION) -> None:
        self.geometry = scenario.obstacle_set
        self.seed_fraction = seed_fraction
        self.clearance = scenario.clearance
        self.separation = scenario.min_separation
        self.dt = scenario.dt
        self.vehicles = len(scenario.vehicles)
        self.obstacles = self.others = len(self.geometry)
        self.intervals = scenario.steps
        super().__init__()

    @property
    def seed_margin(self) -> float:
        """`seed_fraction` clearances, at least SEED_MIN."""
        return max(SEED_MIN, self.seed_fraction * self.clearance)

    def planes(self, lin: FloatArray, t: Triples) -> tuple[FloatArray, FloatArray]:
        """Per triple the row's unit normal (T, 3) and right-hand side (T,): n'x >= rhs at
        every control point of the interval keeps the clearance. Linearised about the
        positions `lin` (N, K+1, 3)."""
        a, b = lin[t.vehicle, t.k], lin[t.vehicle, t.k + 1]
        q = row_point(self.geometry, a, b, t.obstacle)
        first, last = t.k == 0, t.k == self.intervals - 1
        q[first], q[last] = a[first], b[last]
        travel = b - a
        right = np.stack([travel[:, 1], -travel[:, 0]], axis=1)
        norm = np.linalg.norm(right, axis=1)
        right = np.where((norm > 1e-12)[:, None], right / np.where(norm > 1e-12, norm, 1.0)[
            :, None], np.array([1.0, 0.0]))
        _, point, normal = self.geometry.support(q, t.obstacle, right)
        return normal, np.einsum("tc,tc->t", normal, point) + self.clearance

    def values(self, p: FloatArray, v: FloatArray, t: Triples, normal: FloatArray,
               rhs: FloatArray) -> FloatArray:
        """Per triple the smallest n'x - rhs over the interval's control points at (p, v)
        (>= 0: the row holds)."""
        points = interval_points(p, v, t, self.dt)  # (T, 3 points, 3)
        slack: FloatArray = np.einsum("tpc,tc->tp", points, normal).min(axis=1) - rhs
        return slack

    def offsets(self, rhs: FloatArray) -> FloatArray:
        """n'x >= R + offset with offset = rhs - R, the same for the three points."""
        return np.tile(rhs - self.separation, 3)

    def near(self, p: FloatArray, v: FloatArray, reach: float) -> Triples:
        """Triples whose interval's control points' box lies within clearance + `reach` of
        the obstacle's box (a superset of those whose motion comes that close)."""
        cp = control_points(p, v, self.dt)
        lo, hi = cp.min(axis=2).reshape(-1, 3), cp.max(axis=2).reshape(-1, 3)
        box, obstacle = self.geometry.near(lo, hi, self.clearance + reach)
        vehicle, k = np.divmod(box, self.intervals)
        return Triples(vehicle.astype(np.intp), obstacle, k.astype(np.intp))


def concat_rows(a: SeparationRows, b: SeparationRows) -> SeparationRows:
    """Rows of `a` then `b` (offsets 0 where one of them has none)."""
    def offsets(r: SeparationRows) -> FloatArray:
        return np.zeros(len(r)) if r.offset is None else r.offset

    return SeparationRows(
        i=np.concatenate([a.i, b.i]), j=np.concatenate([a.j, b.j]),
        k=np.concatenate([a.k, b.k]), kind=np.concatenate([a.kind, b.kind]),
        coef=np.concatenate([a.coef, b.coef]), offset=np.concatenate([offsets(a), offsets(b)]),
    )
