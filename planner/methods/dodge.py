"""A separated first linearisation point near the synchronised moves: the crowd pushed apart.

With fixed goals the separation-free optimum flies every vehicle straight on one time
profile, and where those lines cross, the first SCP iteration is linearised about vehicles
at nearly one point: rows in arbitrary directions, many of them, one large group too dense
for the dual QP. The plan SCP converges to is those same moves with small dodges. This
module computes such dodges directly, before SCP: position-based relaxation on the time grid
(every pair closer than R (1 + GAP) at a step is pushed apart along its difference, half
each, then each vehicle's displacement from its straight move is smoothed over time), with
starts and goals held. The result is a trajectory the first iteration can be linearised
about: rows there are consistent half-spaces that the point itself (nearly) satisfies.
"""

from __future__ import annotations

import numpy as np

from planner.model.scenario import Scenario
from planner.scp.separation import near_pairs
from planner.types import FloatArray

__all__ = ["DODGE_MIN_VEHICLES", "GAP", "dodged_moves"]

Trajectories = tuple[FloatArray, FloatArray, FloatArray]

#: Fleets of fewer vehicles keep the synchronised moves as their first linearisation point
#: (their crowds are small and cheap; the paper's cases stay as they were).
DODGE_MIN_VEHICLES = 64
#: Pairs are pushed until this far beyond R (units of R) at the steps.
GAP = 0.15
#: Relaxation sweeps, and how often the broad phase is redone.
SWEEPS = 60
REFRESH = 10
#: Smoothing passes of the displacement per sweep (weight of the neighbours' mean).
SMOOTH = 0.5


def _right(motion: FloatArray) -> FloatArray:
    """Unit horizontal directions to the right of `motion` ((..., 3)); x where undefined."""
    right = np.stack([motion[..., 1], -motion[..., 0], np.zeros(motion.shape[:-1])], axis=-1)
    norm = np.linalg.norm(right, axis=-1, keepdims=True)
    fallback = np.zeros_like(right)
    fallback[..., 0] = 1.0
    return np.where(norm > 1e-9, right / np.maximum(norm, 1e-12), fallback)


def dodged_moves(scenario: Scenario, base: Trajectories) -> tuple[Trajectories, float] | None:
    """`base` (the synchronised moves) with every pair pushed R (1 + GAP) apart at the steps
    by smooth dodges (see the module): the trajectories and their smallest pair distance at
    the steps (separation metric, among the pairs the broad phase found), or None when no
    pair of `base` comes closer than R (1 + GAP) at a step (nothing to dodge)."""
    scale, separation, dt = scenario.separation_scale, scenario.min_separation, scenario.dt
    target = separation * (1.0 + GAP)
    q0 = base[0] / scale
    q = q0.copy()
    n, stages = q.shape[0], q.shape[1]
    pi = pj = np.zeros(0, dtype=np.intp)
    worst = np.inf
    moved = False
    for sweep in range(SWEEPS):
        if sweep % REFRESH == 0:
            v = np.gradient(q, dt, axis=1)
            a = np.diff(v, axis=1) / dt
            pi, pj = near_pairs(q, v, a, dt, np.ones(3), 2.0 * target)
        if len(pi) == 0:
            break
        d = q[pi] - q[pj]  # (P, K+1, 3)
        dist = np.linalg.norm(d, axis=2)
        close = dist < target
        close[:, 0] = close[:, -1] = False  # starts and goals stay
        worst = float(dist[:, 1:-1].min()) if stages > 2 else np.inf
        if not close.any():
            break
        moved = True
        p_idx, k_idx = np.nonzero(close)
        diff = d[p_idx, k_idx]
        norm = dist[p_idx, k_idx]
        # Coincident pairs split to the right of their relative motion.
        rel = (q0[pi[p_idx], -1] - q0[pi[p_idx], 0]) - (q0[pj[p_idx], -1] - q0[pj[p_idx], 0])
        unit = np.where((norm > 1e-6)[:, None], diff / np.maximum(norm, 1e-12)[:, None],
                        _right(rel))
        push = 0.5 * (target - norm)[:, None] * unit
        delta = np.zeros_like(q)
        count = np.zeros((n, stages))
        np.add.at(delta, (pi[p_idx], k_idx), push)
        np.add.at(delta, (pj[p_idx], k_idx), -push)
        np.add.at(count, (pi[p_idx], k_idx), 1.0)
        np.add.at(count, (pj[p_idx], k_idx), 1.0)
        q += delta / np.maximum(count, 1.0)[:, :, None]
        # Smooth each vehicle's dodge over time (ends held at zero).
        shift = q - q0
        shift[:, 1:-1] = ((1.0 - SMOOTH) * shift[:, 1:-1]
                          + 0.5 * SMOOTH * (shift[:, :-2] + shift[:, 2:]))
        q = q0 + shift
    if not moved:
        return None
    shift = (q - q0) * scale
    p = base[0] + shift
    v = base[1] + np.gradient(shift, dt, axis=1)
    v[:, 0], v[:, -1] = base[1][:, 0], base[1][:, -1]
    a = base[2] + np.diff(np.gradient(shift, dt, axis=1), axis=1) / dt
    # v and a follow the dodge by finite differences: a linearisation point (its positions
    # and Bernstein middle points), not a trajectory of the dynamics.
    return (p, v, a), worst
