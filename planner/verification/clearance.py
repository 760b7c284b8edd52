"""Continuous-time clearance of trajectories from obstacles, for the independent verifier.

Between steps the motion is the exact quadratic p(s) = p_k + s v_k + s^2/2 a_k. For every
(vehicle, interval, obstacle) that the broad phase cannot rule out, a lower bound clears most
intervals at once: the distance of the chord [p_k, p_k+1] (exact: the distance to a convex
set is convex along a segment) minus the curve's largest deviation from its chord,
dt^2/8 ||a_k||. The intervals whose bound falls under the best distance found so far get the
exact motion sampled at 17 instants and refined by a golden-section search around the best
sample (as `planner.scp.separation.interval_minima` does for pairs); the search assumes the
distance has one minimum near the best sample within a step, which holds for a convex
obstacle and a step much shorter than the obstacle's size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.model.scenario import Scenario
from planner.scp.golden import golden_minimum
from planner.scp.obstacle_rows import ObstacleRows, Triples, chord_nearest
from planner.types import FloatArray

__all__ = ["ClosestObstacle", "closest_obstacle"]

#: Samples per interval before the golden-section refinement, and refinement steps.
SAMPLES = 17
REFINEMENTS = 40


@dataclass(frozen=True)
class ClosestObstacle:
    """The smallest distance of any vehicle's motion to any obstacle's solid."""

    distance: float
    """Signed (negative inside) distance (m)."""
    vehicle: int
    obstacle: int
    time: float
    """When (s)."""


def _interval_minima(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray,
                     t: Triples) -> tuple[FloatArray, FloatArray]:
    """Minimum signed distance over each triple's interval and when within it (s)."""
    geometry = scenario.obstacle_set
    dt = scenario.dt
    p0, v0, half_a = p[t.vehicle, t.k], v[t.vehicle, t.k], 0.5 * a[t.vehicle, t.k]

    def dist(s: FloatArray) -> FloatArray:
        """Distances at times s: (T,) or (T, S)."""
        if s.ndim == 1:
            q = p0 + s[:, None] * v0 + (s * s)[:, None] * half_a
            return geometry.signed_distance(q, t.obstacle)
        q = p0[:, None] + s[..., None] * v0[:, None] + (s * s)[..., None] * half_a[:, None]
        o = np.repeat(t.obstacle, s.shape[1])
        return geometry.signed_distance(q.reshape(-1, 3), o).reshape(s.shape)

    grid = np.linspace(0.0, dt, SAMPLES)
    values = dist(np.broadcast_to(grid, (len(t), SAMPLES)).copy())
    best = np.argmin(values, axis=1)
    step = dt / (SAMPLES - 1)
    lo, hi = np.clip(grid[best] - step, 0.0, dt), np.clip(grid[best] + step, 0.0, dt)
    when, low = golden_minimum(dist, lo, hi, REFINEMENTS)
    sampled = values[np.arange(len(t)), best]
    use = sampled < low
    return np.where(use, sampled, low), np.where(use, grid[best], when)


def closest_obstacle(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray
                     ) -> ClosestObstacle | None:
    """The continuous-time minimum distance to the obstacles (None without obstacles)."""
    if not scenario.obstacles:
        return None
    rows = ObstacleRows(scenario)
    geometry = rows.geometry
    reach = 1.0
    span = float(np.linalg.norm(np.maximum(p.max(axis=(0, 1)), geometry.hi.max(axis=0))
                                - np.minimum(p.min(axis=(0, 1)), geometry.lo.min(axis=0))))
    # Widen the broad phase until it finds something: triples it leaves out are farther
    # than clearance + reach, so the verdict is exact; the figure is exact when it is within
    # clearance + reach, else the smallest of those found (all beyond clearance + reach / 4).
    while True:
        t = rows.near(p, v, reach)
        if len(t):
            return _minimum(scenario, p, v, a, t)
        if reach > 2 * span:  # cannot happen: beyond the span every triple is near
            return None
        reach *= 4.0


def _minimum(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray, t: Triples
             ) -> ClosestObstacle:
    """The continuous-time minimum over the triples `t`."""
    geometry = scenario.obstacle_set
    dt = scenario.dt
    ends = np.concatenate([p[t.vehicle, t.k], p[t.vehicle, t.k + 1]])
    end_d = geometry.signed_distance(ends, np.concatenate([t.obstacle, t.obstacle]))
    at = int(np.argmin(end_d))
    row, late = at % len(t), at >= len(t)
    best = ClosestObstacle(float(end_d[at]), int(t.vehicle[row]), int(t.obstacle[row]),
                           float((t.k[row] + int(late)) * dt))
    chord = chord_nearest(geometry, p[t.vehicle, t.k], p[t.vehicle, t.k + 1], t.obstacle)
    bulge = dt * dt / 8.0 * np.linalg.norm(a[t.vehicle, t.k], axis=1)
    maybe = geometry.signed_distance(chord, t.obstacle) - bulge < best.distance
    if maybe.any():
        sub = Triples(t.vehicle[maybe], t.obstacle[maybe], t.k[maybe])
        minima, when = _interval_minima(scenario, p, v, a, sub)
        i = int(np.argmin(minima))
        if minima[i] < best.distance:
            best = ClosestObstacle(float(minima[i]), int(sub.vehicle[i]), int(sub.obstacle[i]),
                                   float(sub.k[i] * dt + when[i]))
    return best
