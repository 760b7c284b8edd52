"""Goal assignment for `"assignment": "free"` and its CAPT initial guess (Turpin, Michael &
Kumar 2014).

The assignment minimises the total squared distance from starts to goals in the separation
metric ||diag(1/scale) d|| (plain Euclidean for the default scale) with the Hungarian method
(`scipy.optimize.linear_sum_assignment`). Such an assignment makes every pair's start and goal
displacements r0 = S(s_i - s_j), r1 = S(g_i - g_j) satisfy r0'r1 >= 0 (else swapping the two
goals would be cheaper), so on synchronised straight moves r(t) = (1 - phi) r0 + phi r1 with a
common phi(t) in [0, 1], ||r(t)||^2 >= (1 - phi)^2 ||r0||^2 + phi^2 ||r1||^2 >= D^2 / 2 where D
is the smallest start-start or goal-goal distance: the moves keep pairs at least D / sqrt(2)
apart, collision-free whenever D >= sqrt(2) R (CAPT's spacing condition). The moves
themselves are `planner.first_qp.straight_moves`.
"""

from __future__ import annotations

import numpy as np

from planner.types import FloatArray, IntArray

__all__ = ["CAPT_SPACING", "assign_goals", "capt_spacing_holds"]


#: Starts and goals this many R apart (separation metric) make CAPT moves collision-free.
CAPT_SPACING = float(np.sqrt(2.0))


def assign_goals(starts: FloatArray, goals: FloatArray, scale: FloatArray | None = None
                 ) -> IntArray:
    """order[n]: the index of the goal vehicle n flies to, minimising the total squared
    (scaled) distance. Deterministic for given inputs."""
    from scipy.optimize import linear_sum_assignment  # on first use: slow to import

    s = np.ones(3) if scale is None else np.asarray(scale, dtype=float)
    a, b = starts / s, goals / s
    # ||a||^2 + ||b||^2 - 2 a.b, without an (N, N, 3) temporary.
    cost = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    rows, cols = linear_sum_assignment(cost)
    order = np.empty(len(starts), dtype=np.intp)
    order[rows] = cols
    return order


def capt_spacing_holds(starts: FloatArray, goals: FloatArray, separation: float,
                       scale: FloatArray | None = None) -> bool:
    """Are starts and goals each at least sqrt(2) R apart (separation metric)?"""
    s = np.ones(3) if scale is None else np.asarray(scale, dtype=float)
    need = CAPT_SPACING * separation
    for points in (starts / s, goals / s):
        for lo in range(0, len(points), 256):
            d = np.linalg.norm(points[lo:lo + 256, None, :] - points[None, :, :], axis=2)
            d[np.arange(d.shape[0]), lo + np.arange(d.shape[0])] = np.inf
            if d.min(initial=np.inf) < need:
                return False
    return True
