"""The order in which vehicles climb from their homes to their starts.

A vehicle climbs straight up from its home to its start's height (then across, if its home is
not under its start: `gcs.flight.run.boarding`). Two homes nearer than R horizontally would
bring one vehicle up through the other: `climb_waves` puts the one with the higher start in
an earlier wave, so it is up (at its start, R from every other start) before the lower one
leaves the ground. The lower one then climbs towards a point R from it, never nearer.
Vehicles whose columns are clear of every other's all climb in the first wave at once.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

__all__ = ["ON_THE_GROUND_M", "climb_waves"]

#: A start this low (m above its home) is on the ground: that vehicle does not climb.
ON_THE_GROUND_M = 0.05


def climb_waves(homes: ArrayLike, starts: ArrayLike, clearance: float,
                scale: ArrayLike | None = None) -> list[int]:
    """Each vehicle's climb wave (0 first): a vehicle climbs after every vehicle whose home is
    nearer than `clearance` to its own horizontally (in the separation metric's `scale`) and
    whose start is higher. homes, starts: (N, 3) world ENU."""
    home = np.asarray(homes, dtype=float).reshape(-1, 3)
    start = np.asarray(starts, dtype=float).reshape(-1, 3)
    n = home.shape[0]
    waves = [0] * n
    if n < 2:
        return waves
    xy_scale = np.asarray(scale if scale is not None else (1.0, 1.0, 1.0), dtype=float)[:2]
    climbs = start[:, 2] - home[:, 2] > ON_THE_GROUND_M
    pairs = cKDTree(home[:, :2] / xy_scale).query_pairs(clearance * (1.0 - 1e-9),
                                                        output_type="ndarray")
    above: list[list[int]] = [[] for _ in range(n)]
    for i, j in pairs:
        if climbs[i] and climbs[j]:
            high, low = (i, j) if start[i, 2] >= start[j, 2] else (j, i)
            above[int(low)].append(int(high))
    for v in np.argsort(-start[:, 2], kind="stable"):  # the highest first: theirs are known
        waves[int(v)] = 1 + max((waves[u] for u in above[int(v)]), default=-1)
    return waves
