"""A plan's flight figures over time against its limits, per drone and for the fleet: what
a validation report shows (`gcs.show.report`).

Each metric is an (N, T) array of one value per drone and time (the plan's steps; an
acceleration, thrust or body rate is the step's, at its start), its limit, and whether the
bad side is high (speeds) or low (distance). The closest distance is each drone's nearest
neighbour in the separation metric at the steps (k-d tree per step); for a show on the
ground only between drones in the air (`planner.verification.ground`). The continuous-time
figure between the steps is the verifier's (`planner.verification.verify`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from planner.result import Plan
from planner.types import FloatArray
from planner.verification.ground import airborne, starts_on_the_ground

__all__ = ["Metric", "metrics"]

BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class Metric:
    """One figure over time: `values` (N, T) at `times` (T,), its `limit` (None: no bound)
    and whether the limit is a floor (`low`: the smallest value matters) or a ceiling."""

    key: str
    title: str
    unit: str
    times: FloatArray
    values: FloatArray
    limit: float | None
    low: bool = False
    floor: float | None = None
    """A second bound, below (altitude and thrust have both)."""

    def worst_per_drone(self) -> FloatArray:
        """Each drone's worst value (min for a floor, max for a ceiling; NaN-free)."""
        values = np.where(np.isfinite(self.values), self.values,
                          np.inf if self.low else -np.inf)
        worst: FloatArray = values.min(axis=1) if self.low else values.max(axis=1)
        return worst

    def passes(self, tolerance: float) -> BoolArray:
        """Per drone: within the bounds (with `tolerance`)."""
        worst = self.worst_per_drone()
        ok = np.ones(len(worst), dtype=bool)
        if self.limit is not None:
            ok &= (worst >= self.limit - tolerance) if self.low else (
                worst <= self.limit + tolerance)
        if self.floor is not None:
            ok &= self.values.min(axis=1) >= self.floor - tolerance
        return ok


def _nearest(plan: Plan, p: FloatArray, flying: BoolArray) -> FloatArray:
    """(N, T) each drone's nearest flying neighbour's distance (separation metric; inf on
    the ground or alone in the air)."""
    scale = plan.scenario.separation_scale
    n, steps = p.shape[0], p.shape[1]
    out = np.full((n, steps), np.inf)
    for k in range(steps):
        up = np.flatnonzero(flying[:, k])
        if len(up) < 2:
            continue
        distance, _ = cKDTree(p[up, k] / scale).query(p[up, k] / scale, k=2)
        out[up, k] = distance[:, 1]
    return out


def metrics(plan: Plan) -> list[Metric]:
    """Every figure the report draws, in its order."""
    scenario = plan.scenario
    lim = scenario.limits
    p, v, a = plan.positions(), plan.velocities(), plan.accelerations()
    steps = a.shape[1]
    times = np.arange(steps + 1) * scenario.dt
    if starts_on_the_ground(plan.sequence):
        up = airborne(p, v, a)
        flying = np.zeros((p.shape[0], steps + 1), dtype=bool)
        flying[:, :-1] |= up
        flying[:, 1:] |= up
    else:
        flying = np.ones((p.shape[0], steps + 1), dtype=bool)
    a_full = np.concatenate([a, np.zeros((a.shape[0], 1, 3))], axis=1)  # rest at the end
    thrust = np.stack([np.append(t.thrust, t.thrust[-1]) for t in plan.vehicles])
    rates = np.stack([np.vstack([t.body_rates, t.body_rates[-1:]]) for t in plan.vehicles])
    vmax, amax = lim.velocity_max, lim.acceleration_max
    separation = scenario.min_separation * float(scenario.separation_scale.min())
    return [
        Metric("distance", "Closest distance between drones in the air", "m", times,
               _nearest(plan, p, flying), separation, low=True),
        Metric("altitude", "Altitude", "m", times, p[:, :, 2], float(lim.position_max[2]),
               floor=float(lim.position_min[2])),
        Metric("speed_xy", "Horizontal speed", "m/s", times,
               np.hypot(v[:, :, 0], v[:, :, 1]),
               None if vmax is None else math.hypot(vmax[0], vmax[1])),
        Metric("speed_z", "Vertical speed", "m/s", times, np.abs(v[:, :, 2]),
               None if vmax is None else float(vmax[2])),
        Metric("accel_xy", "Horizontal acceleration", "m/s²", times,
               np.hypot(a_full[:, :, 0], a_full[:, :, 1]),
               None if amax is None else math.hypot(amax[0], amax[1])),
        Metric("accel_z", "Vertical acceleration", "m/s²", times, np.abs(a_full[:, :, 2]),
               None if amax is None else float(amax[2])),
        Metric("thrust", "Thrust (mass-normalised)", "m/s²", times, thrust,
               float(lim.thrust_max), floor=float(lim.thrust_min)),
        Metric("body_rate", "Roll and pitch rate", "rad/s", times,
               np.abs(rates[:, :, :2]).max(axis=2), float(lim.body_rate_max)),
    ]
