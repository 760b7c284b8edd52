"""Rows keeping the planned vehicles R + margin from the fixed trajectories (`planner.fixed`).

For planned vehicle i, fixed vehicle f and interval [t_k, t_k+1], the relative motion
r(s) = S (p_i(s) - q_f(s)) is a quadratic with Bernstein control points
S (p_k - q_k), S (p_k + dt/2 v_k - q_k - dt/2 w_k), S (p_k+1 - q_k+1): one direction u
linearised about the previous iterate (as the pair interval rows of `planner.separation`)
and three rows u' S (x_i - x_f) >= R + margin at the control points keep the pair apart over
the whole interval (the margin grows with time, `planner.fixed.margin_at`: the rows of an
interval ask for its largest). q is fixed, so each row is one-sided (`SeparationRows`,
j = -1): coef' x_i >= R + offset, offset = coef' x_f + margin, coef = S u. The broad phase and the
lazy check follow `planner.obstacle_rows`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.plane_cache import Keys, PlaneCache
from planner.qp import SeparationRows
from planner.scenario import Scenario
from planner.separation import _chord_closest, _unit
from planner.types import FloatArray, IntArray

__all__ = ["FixedRows", "FixedTriples"]


#: Triples within this of binding (m, at least) at the linearisation point start an
#: iteration's QP.
SEED_MARGIN = 0.3
#: Boxes compared at once by the broad phase (bounds its memory: 4 arrays of this many
#: 3-vectors).
CHUNK = 1 << 18


@dataclass(frozen=True)
class FixedTriples:
    """(planned vehicle, fixed vehicle, interval) index arrays."""

    vehicle: IntArray
    fixed: IntArray
    k: IntArray

    def __len__(self) -> int:
        return len(self.vehicle)


class FixedRows:
    """The fixed-trajectory rows of one scenario: keys, directions, broad phase, lazy check."""

    def __init__(self, scenario: Scenario) -> None:
        fs = scenario.fixed_set
        self.scale = scenario.separation_scale
        self.separation = scenario.min_separation
        self.dt = scenario.dt
        self.moving = scenario.start_velocities is not None
        self.vehicles = len(scenario.vehicles)
        self.count = len(fs)
        self.intervals = scenario.steps
        self.margins = fs.interval_margins  # (F, K)
        # the fixed vehicles' control points per interval, (F, K, 3 points, 3)
        self.points = np.stack([fs.positions[:, :-1],
                                fs.positions[:, :-1] + 0.5 * self.dt * fs.velocities[:, :-1],
                                fs.positions[:, 1:]], axis=2)
        scaled = self.points / self.scale
        self._lo, self._hi = scaled.min(axis=2), scaled.max(axis=2)  # (F, K, 3)
        self._planes = PlaneCache(lambda lin, keys: self.planes(lin, self.decode(keys)))

    # ---------------------------------------------------------------- keys

    def encode(self, t: FixedTriples) -> Keys:
        return ((t.vehicle.astype(np.int64) * self.count + t.fixed) * self.intervals + t.k)

    def decode(self, keys: Keys) -> FixedTriples:
        k = keys % self.intervals
        vf = keys // self.intervals
        return FixedTriples((vf // self.count).astype(np.intp),
                            (vf % self.count).astype(np.intp), k.astype(np.intp))

    def vehicles_of(self, keys: Keys) -> IntArray:
        return (keys // (self.intervals * self.count)).astype(np.intp)

    # ---------------------------------------------------------------- geometry

    def planes(self, lin: FloatArray, t: FixedTriples) -> tuple[FloatArray, FloatArray]:
        """Per triple the row coefficients coef = S u (T, 3) and the right-hand sides of its
        three rows minus R (T, 3 kinds), linearised about the positions `lin` (N, K+1, 3)."""
        q = self.points[t.fixed, t.k]  # (T, 3 points, 3)
        here = (lin[t.vehicle, t.k] - q[:, 0]) / self.scale
        after = (lin[t.vehicle, t.k + 1] - q[:, 2]) / self.scale
        chord = after - here
        target = _chord_closest(here, after)
        first = (t.k == 0) & (not self.moving)
        last = t.k == self.intervals - 1
        target[first], target[last] = here[first], after[last]
        u = _unit(target, chord, self.separation)
        coef = u / self.scale
        offset = np.einsum("tc,tpc->tp", coef, q) + self.margins[t.fixed, t.k][:, None]
        return coef, offset

    def key_planes(self, lin: FloatArray, keys: Keys) -> tuple[FloatArray, FloatArray]:
        """`planes` of the rows of `keys`, remembered for the current `lin`
        (`planner.plane_cache`)."""
        return self._planes.planes(lin, keys)

    def values(self, p: FloatArray, v: FloatArray, t: FixedTriples, coef: FloatArray,
               offset: FloatArray) -> FloatArray:
        """Per triple the smallest coef' x - R - offset over its three rows at (p, v)."""
        x = np.stack([p[t.vehicle, t.k], p[t.vehicle, t.k] + 0.5 * self.dt * v[t.vehicle, t.k],
                      p[t.vehicle, t.k + 1]], axis=1)  # (T, 3 points, 3)
        return (np.einsum("tpc,tc->tp", x, coef) - self.separation - offset).min(axis=1)

    def near(self, p: FloatArray, v: FloatArray, reach: float) -> FixedTriples:
        """Triples whose interval's control-point boxes (scaled) come within R + margin +
        `reach` of each other: a superset of those whose motion comes that close."""
        cp = np.stack([p[:, :-1], p[:, :-1] + 0.5 * self.dt * v[:, :-1], p[:, 1:]],
                      axis=2) / self.scale  # (N, K, 3, 3)
        lo, hi = cp.min(axis=2), cp.max(axis=2)
        n, k = lo.shape[0], lo.shape[1]
        if self.count == 0 or n == 0:
            z = np.zeros(0, dtype=np.intp)
            return FixedTriples(z, z, z)
        found: list[FixedTriples] = []
        # fixed vehicles in chunks of about CHUNK (planned, fixed, interval) boxes at once
        per = max(1, CHUNK // max(1, n * k))
        for first in range(0, self.count, per):
            f_hi, f_lo = self._hi[first:first + per], self._lo[first:first + per]  # (C, K, 3)
            gap = np.maximum(0.0, np.maximum(lo[:, None] - f_hi[None], f_lo[None] - hi[:, None]))
            need = self.separation + self.margins[first:first + per] + reach  # (C, K)
            close = np.einsum("nfkc,nfkc->nfk", gap, gap) <= need[None] ** 2
            vehicle, fixed, step = np.nonzero(close)
            found.append(FixedTriples(vehicle.astype(np.intp), (fixed + first).astype(np.intp),
                                      step.astype(np.intp)))
        return FixedTriples(*(np.concatenate([getattr(x, name) for x in found])
                              for name in ("vehicle", "fixed", "k")))

    # ---------------------------------------------------------------- the SCP side

    def seed(self, lin: tuple[FloatArray, FloatArray, FloatArray]) -> Keys:
        """Keys of the rows an iteration starts with: within `SEED_MARGIN` of binding."""
        t = self.near(lin[0], lin[1], SEED_MARGIN)
        if len(t) == 0:
            return np.zeros(0, dtype=np.int64)
        keys = self.encode(t)
        coef, offset = self.key_planes(lin[0], keys)
        close = self.values(lin[0], lin[1], t, coef, offset) < SEED_MARGIN
        return np.unique(keys[close])

    def violated(self, lin: FloatArray, p: FloatArray, v: FloatArray, keys: Keys,
                 tolerance: float) -> Keys:
        """Keys not in `keys` of rows (linearised about `lin`) that (p, v) breaks by more
        than `tolerance`, among the triples that come within R + margin at (p, v)."""
        t = self.near(p, v, 0.0)
        if len(t) == 0:
            return np.zeros(0, dtype=np.int64)
        fresh = ~np.isin(self.encode(t), keys)
        t = FixedTriples(t.vehicle[fresh], t.fixed[fresh], t.k[fresh])
        if len(t) == 0:
            return np.zeros(0, dtype=np.int64)
        keys_t = self.encode(t)
        coef, offset = self.key_planes(lin, keys_t)
        bad = self.values(p, v, t, coef, offset) < -tolerance
        return np.unique(keys_t[bad])

    def rows(self, lin: FloatArray, keys: Keys, local: IntArray) -> SeparationRows:
        """The QP rows of `keys`, three per key, kind-major, one-sided."""
        t = self.decode(keys)
        coef, offset = self.key_planes(lin, keys)
        return SeparationRows(
            i=np.tile(local[t.vehicle], 3), j=np.full(3 * len(t), -1, dtype=np.intp),
            k=np.tile(t.k, 3), kind=np.repeat(np.arange(3, dtype=np.intp), len(t)),
            coef=np.tile(coef, (3, 1)), offset=offset.T.reshape(-1),
        )
