"""Thrust and body rates from the planned accelerations and jerk (paper eqs. 14 and 20).

The world frame is ENU with gravity (0, 0, -G): the thrust acceleration a vehicle needs is
a + (0, 0, G), its magnitude is the mass-normalised thrust f, and its direction is the body z
axis. With yaw held at 0, R' j = (f w2, -f w1, df/dt) gives the roll/pitch rates; w3 = 0.
"""

from __future__ import annotations

import numpy as np

from planner.types import FloatArray

__all__ = ["GRAVITY", "THRUST_FLOOR", "body_rates", "jerk_from_accelerations", "thrust"]


#: Standard gravity (m/s^2); the world frame's gravity vector is (0, 0, -GRAVITY).
GRAVITY = 9.81
_UP = np.array([0.0, 0.0, GRAVITY])


def jerk_from_accelerations(accelerations: FloatArray, dt: float,
                            initial: FloatArray | None = None) -> FloatArray:
    """(..., K, 3) jerk (a[k] - a[k-1]) / dt, with a[-1] = `initial` ((..., 3): the
    acceleration before the start), or 0 (the vehicle starts hovering)."""
    a = np.asarray(accelerations, dtype=float)
    before = (np.zeros_like(a[..., :1, :]) if initial is None
              else np.broadcast_to(np.asarray(initial, dtype=float)[..., None, :],
                                   a[..., :1, :].shape))
    previous = np.concatenate([before, a[..., :-1, :]], axis=-2)
    return (a - previous) / dt


def thrust(accelerations: FloatArray) -> FloatArray:
    """(..., K) mass-normalised thrust f = ||a + g|| (m/s^2), paper eq. 14."""
    return np.linalg.norm(np.asarray(accelerations, dtype=float) + _UP, axis=-1)


#: Thrust (m/s^2) below which the body axes are taken as at this thrust: at zero thrust
#: (free fall) the attitude is undefined; the floor keeps the rates finite and huge, so such
#: a plan is reported not flyable instead of carrying NaN.
THRUST_FLOOR = 1e-6


def body_rates(accelerations: FloatArray, jerk: FloatArray) -> FloatArray:
    """(..., K, 3) body rates (w1, w2, 0) in rad/s for yaw 0, paper eq. 20."""
    force = np.asarray(accelerations, dtype=float) + _UP
    f = np.maximum(np.linalg.norm(force, axis=-1, keepdims=True), THRUST_FLOOR)
    # at zero thrust, any body z axis; "up" keeps the rates finite
    z_body = np.where(np.linalg.norm(force, axis=-1, keepdims=True) < THRUST_FLOOR,
                      np.array([0.0, 0.0, 1.0]), force / f)
    # Yaw 0: the body x axis is the world x axis tilted into the plane normal to z_body;
    # with z_body along x (thrust exactly sideways), the world y axis stands in for it.
    heading = np.broadcast_to(np.array([1.0, 0.0, 0.0]), z_body.shape)
    y_body = np.cross(z_body, heading)
    sideways = np.linalg.norm(y_body, axis=-1, keepdims=True) < 1e-12
    y_body = np.where(sideways, np.array([0.0, 1.0, 0.0]), y_body)
    y_body /= np.linalg.norm(y_body, axis=-1, keepdims=True)
    x_body = np.cross(y_body, z_body)
    j = np.asarray(jerk, dtype=float)
    w1 = -np.sum(y_body * j, axis=-1) / f[..., 0]
    w2 = np.sum(x_body * j, axis=-1) / f[..., 0]
    return np.stack([w1, w2, np.zeros_like(w1)], axis=-1)
