"""The discrete double integrator and its exact motion between steps.

Acceleration is held constant over each step of length dt (paper eqs. 6, 7), so the motion
inside a step is an exact quadratic: p(t_k + s) = p_k + s v_k + s^2/2 a_k, v(t_k + s) = v_k + s a_k.
Everything that needs positions between steps (streaming at 50 Hz, continuous-time separation
checks) goes through `interpolate` so there is one definition of that motion.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from planner.types import FloatArray

__all__ = ["MotionSample", "integrate", "interpolate"]



def integrate(
    start_position: ArrayLike, start_velocity: ArrayLike, accelerations: ArrayLike, dt: float
) -> tuple[FloatArray, FloatArray]:
    """Positions and velocities at the K+1 steps from K piecewise-constant accelerations.

    `accelerations` has shape (..., K, 3); the leading axes (e.g. vehicles) broadcast with the
    start arrays of shape (..., 3). Returns (positions, velocities), each (..., K+1, 3).
    """
    a = np.asarray(accelerations, dtype=float)
    p0 = np.asarray(start_position, dtype=float)
    v0 = np.asarray(start_velocity, dtype=float)
    dv = dt * a
    v = np.concatenate([v0[..., None, :], v0[..., None, :] + np.cumsum(dv, axis=-2)], axis=-2)
    dp = dt * v[..., :-1, :] + 0.5 * dt * dt * a
    p = np.concatenate([p0[..., None, :], p0[..., None, :] + np.cumsum(dp, axis=-2)], axis=-2)
    return p, v


class MotionSample(NamedTuple):
    """(position, velocity, acceleration) arrays at sampled times, each (..., M, 3)."""

    position: FloatArray
    velocity: FloatArray
    acceleration: FloatArray


def interpolate(
    positions: ArrayLike,
    velocities: ArrayLike,
    accelerations: ArrayLike,
    dt: float,
    times: ArrayLike,
) -> MotionSample:
    """The exact motion at arbitrary `times` (seconds from the plan's start).

    positions/velocities: (..., K+1, 3) at the steps; accelerations: (..., K, 3), constant over
    each step. Times before 0 hold the start; times after K*dt hold the final state (at rest,
    acceleration zero), which is what a vehicle should do once the plan has ended.
    Returns a `MotionSample` of arrays shaped (..., M, 3) for M times.
    """
    p = np.asarray(positions, dtype=float)
    v = np.asarray(velocities, dtype=float)
    a = np.asarray(accelerations, dtype=float)
    t = np.atleast_1d(np.asarray(times, dtype=float))
    steps = a.shape[-2]
    horizon = steps * dt
    clipped = np.clip(t, 0.0, horizon)
    # A time on a step boundary belongs to the step it starts (t = 0.6 with dt = 0.2 is step
    # 3, though 0.6 / 0.2 = 2.9999999999999996 in floating point).
    k = np.minimum(np.floor(clipped / dt + 1e-9).astype(np.intp), steps - 1)
    s = (clipped - k * dt)[:, None]
    a_k = a[..., k, :]
    pos = p[..., k, :] + s * v[..., k, :] + 0.5 * s * s * a_k
    vel = v[..., k, :] + s * a_k
    outside = ((t < 0.0) | (t >= horizon))[:, None]
    acc = np.where(outside, 0.0, a_k)
    after = t >= horizon
    if np.any(after):
        pos[..., after, :] = p[..., -1:, :]
        vel[..., after, :] = v[..., -1:, :]
    return MotionSample(pos, vel, acc)
