"""How a multicopter's position controller flies a setpoint it is left with.

PX4's (and ArduCopter's) horizontal control is a cascade: a velocity reference from the
position error (`POSITION_GAIN`, MPC_XY_P) plus the setpoint's feed-forward velocity, and an
acceleration from the velocity error (`VELOCITY_GAIN`, MPC_XY_VEL_P_ACC). A vehicle whose
setpoints stop flies on on its last one towards its position plus its feed-forward velocity
over the position gain, and one told to hold a point overshoots it a little on the way. The
station predicts both (a silent vehicle's motion, the others' stops) with `follow`: the same
cascade, stepped at most `STEP_S`, for any number of vehicles at once.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from planner.types import FloatArray

__all__ = ["POSITION_GAIN", "STEP_S", "VELOCITY_GAIN", "follow", "substeps"]

#: Position gain (1/s): PX4's MPC_XY_P default (MPC_Z_P is 1; ArduCopter's PSC_POSXY_P, 1).
POSITION_GAIN = 0.95
#: Velocity gain (1/s): PX4's MPC_XY_VEL_P_ACC default (ArduCopter's PSC_VELXY_P, 2).
VELOCITY_GAIN = 1.8
#: Integration step (s).
STEP_S = 0.02


def follow(position: ArrayLike, velocity: ArrayLike, target: ArrayLike,
           feed_forward: ArrayLike, steps: int, step: float = STEP_S
           ) -> tuple[FloatArray, FloatArray]:
    """Positions and velocities (steps + 1, ..., 3) at 0, `step`, ..., steps * `step` s of
    vehicles at `position`/`velocity` (..., 3) flying the fixed setpoint `target` with the
    velocity `feed_forward` (broadcast to the same shape)."""
    x = np.array(position, dtype=float)
    u = np.array(velocity, dtype=float)
    goal = np.broadcast_to(np.asarray(target, dtype=float), x.shape)
    ahead = np.broadcast_to(np.asarray(feed_forward, dtype=float), x.shape)
    xs = np.empty((steps + 1, *x.shape))
    us = np.empty((steps + 1, *x.shape))
    xs[0], us[0] = x, u
    for k in range(1, steps + 1):
        u = u + step * VELOCITY_GAIN * (ahead + POSITION_GAIN * (goal - x) - u)
        x = x + step * u
        xs[k], us[k] = x, u
    return xs, us


def substeps(dt: float) -> int:
    """Steps of `follow` per `dt` (its step is then dt / substeps, at most `STEP_S`)."""
    return max(1, math.ceil(dt / STEP_S - 1e-9))
