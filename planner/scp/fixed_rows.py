"""Rows keeping the planned vehicles R + margin from the fixed trajectories (`planner.model.fixed`).

For planned vehicle i, fixed vehicle f and interval [t_k, t_k+1], the relative motion
r(s) = S (p_i(s) - q_f(s)) is a quadratic with Bernstein control points
S (p_k - q_k), S (p_k + dt/2 v_k - q_k - dt/2 w_k), S (p_k+1 - q_k+1): one direction u
linearised about the previous iterate (as the pair interval rows of `planner.scp.separation`)
and three rows u' S (x_i - x_f) >= R + margin at the control points keep the pair apart over
the whole interval (the margin grows with time, `planner.model.fixed.margin_at`, and a pair
that starts closer than R is forgiven a deficit shrinking with time,
`planner.model.fixed.relief_at`: the rows of an interval ask for its largest need). q is fixed,
so each row is one-sided (`SeparationRows`, j = -1): coef' x_i >= R + offset,
offset = coef' x_f + margin - forgiven deficit, coef = S u. The broad phase and the
lazy check follow `planner.scp.obstacle_rows` (`planner.scp.lazy_rows`).
"""

from __future__ import annotations

import numpy as np

from planner.model.scenario import Scenario
from planner.scp.lazy_rows import LazyRows, Triples, interval_points
from planner.scp.separation import _chord_closest, _unit
from planner.types import FloatArray

__all__ = ["FixedRows", "interval_boxes"]


#: Triples within this of binding (m, at least) at the linearisation point start an
#: iteration's QP.
SEED_MARGIN = 0.3
#: Boxes compared at once by the broad phase (bounds its memory: 4 arrays of this many
#: 3-vectors).
CHUNK = 1 << 18
#: Intervals per coarse box of the broad phase (`FixedRows.near`).
BLOCK = 10


def interval_boxes(positions: FloatArray, velocities: FloatArray, dt: float, scale: FloatArray
                   ) -> tuple[FloatArray, FloatArray]:
    """(lo, hi), (N, K, 3) each: per trajectory and interval the box of its three control
    points p_k, p_k + dt/2 v_k, p_k+1 (scaled), which holds the interval's motion."""
    start, end = positions[:, :-1], positions[:, 1:]
    middle = start + 0.5 * dt * velocities[:, :-1]
    lo = np.minimum(np.minimum(start, middle), end) / scale
    hi = np.maximum(np.maximum(start, middle), end) / scale
    return lo, hi


def _box_gap2(lo: FloatArray, hi: FloatArray, other_lo: FloatArray, other_hi: FloatArray
              ) -> FloatArray:
    """Squared distance between boxes [lo, hi] and [other_lo, other_hi] (broadcast, last
    axis the coordinates)."""
    gap = np.maximum(0.0, np.maximum(lo - other_hi, other_lo - hi))
    gap2: FloatArray = np.einsum("...c,...c->...", gap, gap)
    return gap2


class FixedRows(LazyRows):
    """The fixed-trajectory rows of one scenario: directions and the broad phase
    (`planner.scp.lazy_rows` seeds them and checks them lazily)."""

    def __init__(self, scenario: Scenario) -> None:
        fs = scenario.fixed_set
        self.scale = scenario.separation_scale
        self.separation = scenario.min_separation
        self.dt = scenario.dt
        self.moving = scenario.start_velocities is not None
        self.vehicles = len(scenario.vehicles)
        self.count = self.others = len(fs)
        self.intervals = scenario.steps
        self.fixed_set = fs
        self.margins = fs.interval_margins  # (F, K): the broad phase's need (no deficit)
        self._positions, self._velocities = fs.positions, fs.velocities
        self._lo, self._hi = interval_boxes(fs.positions, fs.velocities, self.dt,
                                            self.scale)  # (F, K, 3)
        # the same over blocks of BLOCK intervals: the broad phase's first, coarse test
        self._firsts = np.arange(0, self.intervals, BLOCK)
        self._block_lo = np.minimum.reduceat(self._lo, self._firsts, axis=1)
        self._block_hi = np.maximum.reduceat(self._hi, self._firsts, axis=1)
        self._block_margin = np.maximum.reduceat(self.margins, self._firsts, axis=1)
        super().__init__()

    @property
    def seed_margin(self) -> float:
        return SEED_MARGIN

    def planes(self, lin: FloatArray, t: Triples) -> tuple[FloatArray, FloatArray]:
        """Per triple the row coefficients coef = S u (T, 3) and the right-hand sides of its
        three rows minus R (T, 3 kinds), linearised about the positions `lin` (N, K+1, 3)."""
        start = self._positions[t.fixed, t.k]
        q = np.stack([start, start + 0.5 * self.dt * self._velocities[t.fixed, t.k],
                      self._positions[t.fixed, t.k + 1]], axis=1)  # (T, 3 points, 3)
        here = (lin[t.vehicle, t.k] - q[:, 0]) / self.scale
        after = (lin[t.vehicle, t.k + 1] - q[:, 2]) / self.scale
        chord = after - here
        target = _chord_closest(here, after)
        first = (t.k == 0) & (not self.moving)
        last = t.k == self.intervals - 1
        target[first], target[last] = here[first], after[last]
        u = _unit(target, chord, self.separation)
        coef = u / self.scale
        extra = self.fixed_set.interval_extra(t.vehicle, t.fixed, t.k)
        offset = np.einsum("tc,tpc->tp", coef, q) + extra[:, None]
        return coef, offset

    def values(self, p: FloatArray, v: FloatArray, t: Triples, coef: FloatArray,
               offset: FloatArray) -> FloatArray:
        """Per triple the smallest coef' x - R - offset over its three rows at (p, v)."""
        x = interval_points(p, v, t, self.dt)  # (T, 3 points, 3)
        slack: FloatArray = (np.einsum("tpc,tc->tp", x, coef) - self.separation
                             - offset).min(axis=1)
        return slack

    def offsets(self, offset: FloatArray) -> FloatArray:
        """coef' x_i >= R + offset, one offset per control point."""
        return offset.T.reshape(-1)

    def near(self, p: FloatArray, v: FloatArray, reach: float) -> Triples:
        """Triples whose interval's control-point boxes (scaled) come within R + margin +
        `reach` of each other: a superset of those whose motion comes that close. Boxes
        over BLOCK intervals are compared first; only the intervals of blocks that come
        that close are compared one by one."""
        n = p.shape[0]
        if self.count == 0 or n == 0:
            return Triples.empty()
        lo, hi = interval_boxes(p, v, self.dt, self.scale)  # (N, K, 3)
        block_lo = np.minimum.reduceat(lo, self._firsts, axis=1)  # (N, B, 3)
        block_hi = np.maximum.reduceat(hi, self._firsts, axis=1)
        blocks = len(self._firsts)
        found: list[Triples] = []
        # fixed vehicles in chunks of about CHUNK (planned, fixed, interval) boxes at once
        per = max(1, CHUNK // max(1, n * blocks * BLOCK))
        for first in range(0, self.count, per):
            f_hi, f_lo = self._block_hi[first:first + per], self._block_lo[first:first + per]
            need = self.separation + self._block_margin[first:first + per] + reach  # (C, B)
            vehicle, fixed, block = np.nonzero(
                _box_gap2(block_lo[:, None], block_hi[:, None], f_lo[None], f_hi[None])
                <= need[None] ** 2)
            if vehicle.size == 0:
                continue
            # every interval of the close blocks
            k = (block[:, None] * BLOCK + np.arange(BLOCK)[None, :]).reshape(-1)
            vehicle = np.repeat(vehicle, BLOCK)
            fixed = np.repeat(fixed + first, BLOCK)
            inside = k < self.intervals
            vehicle, fixed, k = vehicle[inside], fixed[inside], k[inside]
            close = (_box_gap2(lo[vehicle, k], hi[vehicle, k], self._lo[fixed, k],
                               self._hi[fixed, k])
                     <= (self.separation + self.margins[fixed, k] + reach) ** 2)
            found.append(Triples(vehicle[close].astype(np.intp),
                                      fixed[close].astype(np.intp), k[close].astype(np.intp)))
        if not found:
            return Triples.empty()
        return Triples(*(np.concatenate([getattr(x, name) for x in found])
                         for name in ("vehicle", "other", "k")))
