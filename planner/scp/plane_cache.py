"""Row planes remembered per key for one linearisation point.

An SCP iteration asks for the same one-sided rows (obstacle or fixed-trajectory planes)
again after each round of violated rows; the planes depend only on the linearisation point
and the row's key, so each is computed once per iteration.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from planner.types import FloatArray

__all__ = ["Keys", "PlaneCache"]

#: Row keys (int64, one per row).
Keys = NDArray[np.int64]


class PlaneCache:
    """`compute(lin, keys) -> (coef, offset)` (row-major arrays, one row per key) answered
    from memory for keys already computed at the same `lin` (compared by identity)."""

    def __init__(self, compute: Callable[[FloatArray, Keys], tuple[FloatArray, FloatArray]]
                 ) -> None:
        self._compute = compute
        self._lin: FloatArray | None = None
        self._keys: Keys = np.zeros(0, dtype=np.int64)
        self._coef: FloatArray | None = None
        self._offset: FloatArray | None = None

    def planes(self, lin: FloatArray, keys: Keys) -> tuple[FloatArray, FloatArray]:
        """The planes of `keys` (sorted or not) at `lin`."""
        if self._lin is not lin:
            self._lin, self._keys, self._coef, self._offset = lin, keys[:0], None, None
        missing = np.setdiff1d(keys, self._keys)
        if missing.size:
            coef, offset = self._compute(lin, missing)
            merged = np.concatenate([self._keys, missing])
            order = np.argsort(merged, kind="stable")
            self._keys = merged[order]
            self._coef = (coef if self._coef is None
                          else np.concatenate([self._coef, coef]))[order]
            self._offset = (offset if self._offset is None
                            else np.concatenate([self._offset, offset]))[order]
        at = np.searchsorted(self._keys, keys)
        assert self._coef is not None and self._offset is not None
        return self._coef[at], self._offset[at]
