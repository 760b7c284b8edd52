"""Vectorised golden-section search: many one-dimensional minimisations at once."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planner.types import FloatArray

__all__ = ["golden_minimum"]

#: (sqrt(5) - 1) / 2: each step keeps this fraction of the bracket.
RATIO = (np.sqrt(5.0) - 1.0) / 2.0


def golden_minimum(f: Callable[[FloatArray], FloatArray], lo: FloatArray, hi: FloatArray,
                   steps: int) -> tuple[FloatArray, FloatArray]:
    """For each bracket [lo, hi] the point of least f found by `steps` golden-section steps,
    and f there: exact for a function with one minimum in the bracket (a convex one), to
    RATIO^steps of the bracket. f maps an array of points (one per bracket) to values."""
    x1, x2 = hi - RATIO * (hi - lo), lo + RATIO * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(steps):
        left = f1 < f2  # the minimum lies in [lo, x2]: drop (x2, hi]
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        probe = np.where(left, hi - RATIO * (hi - lo), lo + RATIO * (hi - lo))
        fp = f(probe)
        x1, x2, f1, f2 = (np.where(left, probe, x2), np.where(left, x1, probe),
                          np.where(left, fp, f2), np.where(left, f1, fp))
    return np.where(f1 < f2, x1, x2), np.minimum(f1, f2)
