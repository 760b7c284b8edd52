"""Continuous-time distance of planned trajectories from the fixed ones, for the verifier.

Planned and fixed vehicles move alike inside a step (p_k + s v_k + s^2/2 a_k), so each
(planned, fixed) pair's distance over an interval is a pair distance of
`planner.scp.separation`: the step distances give an upper bound on the minimum, the chord bound
(`interval_lower_bounds`) clears most intervals, and `interval_minima` measures the rest
exactly. Each fixed vehicle asks for R + its margin (growing with time,
`planner.model.fixed.margin_at`), less what a pair that started closer than R is still
forgiven (`planner.model.fixed.relief_at`), so the pair judged closest is the one with the
least slack (distance - that need).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.model.scenario import Scenario
from planner.scp.separation import interval_lower_bounds, interval_minima
from planner.types import FloatArray

__all__ = ["ClosestFixed", "closest_fixed"]


@dataclass(frozen=True)
class ClosestFixed:
    """The planned vehicle that comes nearest (least slack) to a fixed one."""

    distance: float
    """Scaled distance (m, the separation metric)."""
    required: float
    """R + that fixed vehicle's margin (m)."""
    vehicle: int
    fixed: int
    time: float


def closest_fixed(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray
                  ) -> ClosestFixed | None:
    """The least-slack (planned, fixed) approach over continuous time; None without fixed
    trajectories or planned vehicles."""
    fs = scenario.fixed_set
    n, count = len(p), len(fs)
    if n == 0 or count == 0:
        return None
    scale = scenario.separation_scale
    dt = scenario.dt
    # one pair array: planned vehicles 0..n-1, fixed ones n..n+F-1 (pairs i < j)
    positions = np.concatenate([p, fs.positions])
    velocities = np.concatenate([v, fs.velocities])
    accelerations = np.concatenate([a, fs.accelerations])
    separation = scenario.min_separation
    i = np.repeat(np.arange(n), count)
    f_of = np.tile(np.arange(count), n)
    j = n + f_of
    steps = np.linalg.norm((p[i] - fs.positions[f_of]) / scale, axis=-1)  # (pairs, K+1)
    step_need = separation + fs.step_extra(i, f_of)  # (pairs, K+1)
    slack = steps - step_need
    pair, k = np.unravel_index(int(np.argmin(slack)), slack.shape)
    best = ClosestFixed(float(steps[pair, k]), float(step_need[pair, k]), int(i[pair]),
                        int(f_of[pair]), float(k * dt))
    best_slack = float(slack[pair, k])
    # intervals whose lower bound goes under the best slack found at the steps (their
    # need is that of the interval: its margin at the end)
    for f in range(count):
        mine = j == n + f
        top = separation + float(fs.interval_margins[f].max(initial=0.0))
        maybe = interval_lower_bounds(positions, accelerations, dt, scale,
                                      best_slack + top, (i[mine], j[mine]))
        if len(maybe) == 0:
            continue
        minima, when = interval_minima(positions, velocities, accelerations, dt, scale, maybe)
        need = separation + fs.interval_extra(maybe.i, np.full(len(maybe.k), f), maybe.k)
        idx = int(np.argmin(minima - need))
        if minima[idx] - need[idx] < best_slack:
            best_slack = float(minima[idx] - need[idx])
            best = ClosestFixed(float(minima[idx]), float(need[idx]), int(maybe.i[idx]), f,
                                float(maybe.k[idx] * dt + when[idx]))
    if not math.isfinite(best.distance):
        return ClosestFixed(math.nan, best.required, best.vehicle, best.fixed, best.time)
    return best
