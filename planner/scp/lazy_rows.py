"""One-sided rows that start an iteration's QP when nearly binding and join it when broken.

Obstacle rows (`planner.scp.obstacle_rows`) and fixed-trajectory rows (`planner.scp.fixed_rows`)
bind one planned vehicle on one interval against one other thing (an obstacle, a fixed
vehicle). Both run the same algorithm over (vehicle, other, interval) triples: a broad
phase (`near`) finds the triples that can come close; an iteration's QP starts with those
within a seed margin of binding at the linearisation point (`seed`); after each solve the
rows the iterate breaks are added (`violated`). `LazyRows` is that algorithm once; each
source gives its broad phase, planes and row values.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from planner.scp.plane_cache import Keys, PlaneCache
from planner.scp.qp import SeparationRows
from planner.types import FloatArray, IntArray

__all__ = ["LazyRows", "Triples", "interval_points"]


@dataclass(frozen=True)
class Triples:
    """(planned vehicle, other, interval) index arrays; the other is an obstacle or a fixed
    vehicle, by the source."""

    vehicle: IntArray
    other: IntArray
    k: IntArray

    @property
    def obstacle(self) -> IntArray:
        return self.other

    @property
    def fixed(self) -> IntArray:
        return self.other

    def __len__(self) -> int:
        return len(self.vehicle)

    def take(self, which: IntArray | np.ndarray) -> Triples:
        """The triples selected by the index or mask `which`."""
        return Triples(self.vehicle[which], self.other[which], self.k[which])

    @staticmethod
    def empty() -> Triples:
        z = np.zeros(0, dtype=np.intp)
        return Triples(z, z, z)


def interval_points(p: FloatArray, v: FloatArray, t: Triples, dt: float) -> FloatArray:
    """(T, 3 points, 3): per triple the Bernstein control points p_k, p_k + dt/2 v_k, p_k+1
    of its vehicle's interval."""
    start = p[t.vehicle, t.k]
    return np.stack([start, start + 0.5 * dt * v[t.vehicle, t.k], p[t.vehicle, t.k + 1]],
                    axis=1)


class LazyRows(ABC):
    """Keys, seeding and the lazy check of one source of one-sided rows. A subclass sets
    `others` (obstacles or fixed vehicles), `intervals`, `dt`, `separation` and calls
    `__init__`; it gives `near`, `planes`, `values`, `offsets` and `seed_margin`."""

    others: int
    intervals: int

    def __init__(self) -> None:
        self._planes = PlaneCache(lambda lin, keys: self.planes(lin, self.decode(keys)))

    # ---------------------------------------------------------------- the source's part

    @abstractmethod
    def near(self, p: FloatArray, v: FloatArray, reach: float) -> Triples:
        """Triples whose interval comes within reach of binding (a superset)."""
        ...

    @abstractmethod
    def planes(self, lin: FloatArray, t: Triples) -> tuple[FloatArray, FloatArray]:
        """Per triple the row's coefficients (T, 3) and its right-hand side, linearised
        about the positions `lin` (N, K+1, 3)."""
        ...

    @abstractmethod
    def values(self, p: FloatArray, v: FloatArray, t: Triples, coef: FloatArray,
               offset: FloatArray) -> FloatArray:
        """Per triple the smallest slack of its three rows at (p, v) (>= 0: they hold)."""
        ...

    @abstractmethod
    def offsets(self, offset: FloatArray) -> FloatArray:
        """The `SeparationRows.offset` of the rows of triples with right-hand sides
        `offset` (three per triple, kind-major)."""
        ...

    @property
    @abstractmethod
    def seed_margin(self) -> float:
        """Rows within this of binding at the linearisation point start an iteration."""
        ...

    # ---------------------------------------------------------------- keys

    def encode(self, t: Triples) -> Keys:
        return (t.vehicle.astype(np.int64) * self.others + t.other) * self.intervals + t.k

    def decode(self, keys: Keys) -> Triples:
        k = keys % self.intervals
        vo = keys // self.intervals
        return Triples((vo // self.others).astype(np.intp),
                       (vo % self.others).astype(np.intp), k.astype(np.intp))

    def vehicles_of(self, keys: Keys) -> IntArray:
        return (keys // (self.intervals * self.others)).astype(np.intp)

    def key_planes(self, lin: FloatArray, keys: Keys) -> tuple[FloatArray, FloatArray]:
        """`planes` of the rows of `keys`, remembered for the current `lin`
        (`planner.scp.plane_cache`)."""
        return self._planes.planes(lin, keys)

    # ---------------------------------------------------------------- the SCP side

    def seed(self, lin: tuple[FloatArray, FloatArray, FloatArray]) -> Keys:
        """Keys of the rows an iteration starts with: within `seed_margin` of binding at
        the linearisation point."""
        margin = self.seed_margin
        t = self.near(lin[0], lin[1], margin)
        if len(t) == 0:
            return np.zeros(0, dtype=np.int64)
        keys = self.encode(t)
        coef, offset = self.key_planes(lin[0], keys)
        close = self.values(lin[0], lin[1], t, coef, offset) < margin
        return np.unique(keys[close])

    def violated(self, lin: FloatArray, p: FloatArray, v: FloatArray, keys: Keys,
                 tolerance: float) -> Keys:
        """Keys not in `keys` of rows (linearised about positions `lin`) that (p, v) breaks
        by more than `tolerance`, among the triples that come within reach of binding at
        (p, v): farther ones hold whatever their row says."""
        t = self.near(p, v, 0.0)
        if len(t) == 0:
            return np.zeros(0, dtype=np.int64)
        t = t.take(~np.isin(self.encode(t), keys))
        if len(t) == 0:
            return np.zeros(0, dtype=np.int64)
        keys_t = self.encode(t)
        coef, offset = self.key_planes(lin, keys_t)
        bad = self.values(p, v, t, coef, offset) < -tolerance
        return np.unique(keys_t[bad])

    def rows(self, lin: FloatArray, keys: Keys, local: IntArray) -> SeparationRows:
        """The QP rows of `keys`: three per key (kinds 0, 1, 2, kind-major like the
        separation rows), one-sided (j = -1). `local` maps scenario vehicle indices to the
        group's."""
        t = self.decode(keys)
        coef, offset = self.key_planes(lin, keys)
        return SeparationRows(
            i=np.tile(local[t.vehicle], 3), j=np.full(3 * len(t), -1, dtype=np.intp),
            k=np.tile(t.k, 3), kind=np.repeat(np.arange(3, dtype=np.intp), len(t)),
            coef=np.tile(coef, (3, 1)), offset=self.offsets(offset),
        )
