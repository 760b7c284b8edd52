"""Every one-sided row source of a scenario behind one key space, for the SCP loop.

Obstacle rows (`planner.scp.obstacle_rows`) and fixed-trajectory rows (`planner.scp.fixed_rows`)
each bind one planned vehicle against something outside the QP. The SCP loop treats them
alike (seed, lazy check, rows, owners), so `OneSidedRows` gives each source a range of
keys (offset by a base) and answers for all of them; its rows are kind-major over all keys,
as the group solver reads their multipliers.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from planner.model.scenario import Scenario
from planner.scp.fixed_rows import FixedRows
from planner.scp.obstacle_rows import SEED_FRACTION, ObstacleRows
from planner.scp.qp import SeparationRows
from planner.types import FloatArray, IntArray

__all__ = ["OneSidedRows"]

Keys = NDArray[np.int64]


class _Source(Protocol):
    def seed(self, lin: tuple[FloatArray, FloatArray, FloatArray]) -> Keys: ...
    def violated(self, lin: FloatArray, p: FloatArray, v: FloatArray, keys: Keys,
                 tolerance: float) -> Keys: ...
    def vehicles_of(self, keys: Keys) -> IntArray: ...
    def rows(self, lin: FloatArray, keys: Keys, local: IntArray) -> SeparationRows: ...


class OneSidedRows:
    """The scenario's obstacle and fixed-trajectory rows in one key space."""

    def __init__(self, scenario: Scenario, obstacle_seed: float = SEED_FRACTION) -> None:
        n, k = len(scenario.vehicles), scenario.steps
        self.sources: list[_Source] = []
        self.bases: list[int] = []
        base = 0
        if scenario.obstacles:
            self.sources.append(ObstacleRows(scenario, obstacle_seed))
            self.bases.append(base)
            base += n * len(scenario.obstacles) * k
        if scenario.fixed:
            self.sources.append(FixedRows(scenario))
            self.bases.append(base)
            base += n * len(scenario.fixed) * k
        self.bases.append(base)  # the end of the last range

    def _split(self, keys: Keys) -> list[Keys]:
        """`keys` (sorted) per source, as that source's own keys."""
        edges = np.searchsorted(keys, self.bases)
        return [keys[edges[s]:edges[s + 1]] - self.bases[s] for s in range(len(self.sources))]

    def seed(self, lin: tuple[FloatArray, FloatArray, FloatArray]) -> Keys:
        return np.concatenate([src.seed(lin) + base
                               for src, base in zip(self.sources, self.bases, strict=False)]
                              + [np.zeros(0, dtype=np.int64)])

    def violated(self, lin: FloatArray, p: FloatArray, v: FloatArray, keys: Keys,
                 tolerance: float) -> Keys:
        parts = self._split(np.sort(keys))
        return np.concatenate([src.violated(lin, p, v, own, tolerance) + base
                               for src, base, own in zip(self.sources, self.bases, parts,
                                                         strict=False)]
                              + [np.zeros(0, dtype=np.int64)])

    def vehicles_of(self, keys: Keys) -> IntArray:
        out = np.zeros(len(keys), dtype=np.intp)
        for s, src in enumerate(self.sources):
            mine = (keys >= self.bases[s]) & (keys < self.bases[s + 1])
            out[mine] = src.vehicles_of(keys[mine] - self.bases[s])
        return out

    def rows(self, lin: FloatArray, keys: Keys, local: IntArray) -> SeparationRows:
        """Three rows per key (sorted keys), kind-major over all of them."""
        parts = [src.rows(lin, own, local)
                 for src, own in zip(self.sources, self._split(keys), strict=False)
                 if own.size]
        if not parts:
            return SeparationRows.empty()

        def kind_major(name: str) -> Any:
            """`name` of every part, kind-major over all their keys."""
            blocks = [np.asarray(getattr(r, name)).reshape(3, len(r) // 3, -1) for r in parts]
            merged = np.concatenate(blocks, axis=1)
            flat = merged.reshape(-1, merged.shape[2])
            return flat[:, 0] if merged.shape[2] == 1 else flat

        return SeparationRows(i=kind_major("i"), j=kind_major("j"), k=kind_major("k"),
                              kind=kind_major("kind"), coef=kind_major("coef"),
                              offset=kind_major("offset"))
