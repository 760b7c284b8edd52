"""Thrust and body rates from the planned accelerations and jerk (paper eqs. 14 and 20).

The world frame is ENU with gravity (0, 0, -G): the thrust acceleration a vehicle needs is
a + (0, 0, G), its magnitude is the mass-normalised thrust f, and its direction is the body z
axis. With yaw held at 0, R' j = (f w2, -f w1, df/dt) gives the roll/pitch rates; w3 = 0.
"""

from __future__ import annotations

import numpy as np

from planner.types import FloatArray

__all__ = ["GRAVITY", "THRUST_FLOOR", "body_rates", "jerk_from_accelerations", "thrust",
           "thrust_cost"]


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
    jerk: FloatArray = (a - previous) / dt
    return jerk


def thrust(accelerations: FloatArray) -> FloatArray:
    """(..., K) mass-normalised thrust f = ||a + g|| (m/s^2), paper eq. 14."""
    f: FloatArray = np.linalg.norm(np.asarray(accelerations, dtype=float) + _UP, axis=-1)
    return f


#: Thrust (m/s^2) below which the body axes are taken as at this thrust: at zero thrust
#: (free fall) the attitude is undefined; the floor keeps the rates finite and huge, so such
#: a plan is reported not flyable instead of carrying NaN.
THRUST_FLOOR = 1e-6


def body_rates(accelerations: FloatArray, jerk: FloatArray) -> FloatArray:
    """(..., K, 3) body rates (w1, w2, 0) in rad/s for yaw 0, paper eq. 20. Written out per
    component (the cross products with the world x axis have two zero terms): a show-scale
    plan has millions of samples."""
    force = np.asarray(accelerations, dtype=float) + _UP
    fx, fy, fz = force[..., 0], force[..., 1], force[..., 2]
    norm = np.sqrt(fx * fx + fy * fy + fz * fz)
    f = np.maximum(norm, THRUST_FLOOR)
    # at zero thrust, any body z axis; "up" keeps the rates finite
    free_fall = norm < THRUST_FLOOR
    zx = np.where(free_fall, 0.0, fx / f)
    zy = np.where(free_fall, 0.0, fy / f)
    zz = np.where(free_fall, 1.0, fz / f)
    # Yaw 0: the body y axis is z_body x (1, 0, 0) = (0, zz, -zy), normalised; with z_body
    # along x (thrust exactly sideways) the world y axis stands in for it.
    length = np.sqrt(zz * zz + zy * zy)
    sideways = length < 1e-12
    safe = np.where(sideways, 1.0, length)
    yx = np.zeros_like(zx)
    yy = np.where(sideways, 1.0, zz / safe)
    yz = np.where(sideways, 0.0, -zy / safe)
    # x_body = y_body x z_body
    xx = yy * zz - yz * zy
    xy = yz * zx - yx * zz
    xz = yx * zy - yy * zx
    j = np.asarray(jerk, dtype=float)
    jx, jy, jz = j[..., 0], j[..., 1], j[..., 2]
    w1 = -(yx * jx + yy * jy + yz * jz) / f
    w2 = (xx * jx + xy * jy + xz * jz) / f
    return np.stack([w1, w2, np.zeros_like(w1)], axis=-1)


def thrust_cost(accelerations: FloatArray) -> float:
    """The paper's total-thrust cost sum ||a + g||^2 over vehicles and steps."""
    a = np.asarray(accelerations)
    return float(np.sum(a[..., :2] ** 2) + np.sum((a[..., 2] + GRAVITY) ** 2))
