"""Which box constraints bind, or nearly bind, for given trajectories.

Most of the position, velocity, acceleration and jerk bounds are far from active, and each
one the QP carries costs interior-point work. The SCP loop therefore starts a QP with the
boxes that were close to binding at the previous iterate (`near_boxes`) and adds any that
the new solution breaks (`broken_boxes`), like it does with separation rows.
"""

from __future__ import annotations

import numpy as np

from planner.model.scenario import Scenario
from planner.scp.qp import A, BoxMask, P, V
from planner.types import FloatArray

__all__ = ["broken_boxes", "near_boxes"]


#: A bound is "near" when the iterate uses at least this fraction of it (velocity,
#: acceleration, jerk), or is closer to a wall than this fraction of the box's size.
NEAR_FRACTION = 0.5
WALL_FRACTION = 0.1
#: The same for the dual group QPs (`planner.scp.dual`), where every box row is a dual variable
#: coupled to all of its vehicle's other rows: only boxes that nearly bind are worth it.
DUAL_NEAR_FRACTION = 0.9
DUAL_WALL_FRACTION = 0.01


def _masks(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray,
           fraction: float, wall: FloatArray | float, extra: float) -> BoxMask:
    """A `BoxMask` over the vehicles of `p` flagging positions closer than `wall` to a wall
    (negative: beyond it) and |v|, |a|, |jerk| above fraction * limit + extra."""
    lim = scenario.limits
    n, stages = p.shape[0], p.shape[1]
    bounds = np.zeros((n, stages, 3, 3), dtype=bool)
    bounds[:, :, P, :] = (p < lim.position_min + wall) | (p > lim.position_max - wall)
    if lim.velocity_max is not None:
        bounds[:, :, V, :] = np.abs(v) > lim.velocity_max * fraction + extra
    if lim.acceleration_max is not None:
        bounds[:, :-1, A, :] = np.abs(a) > lim.acceleration_max * fraction + extra
    jerk = np.zeros(a.shape, dtype=bool)
    if lim.jerk_max is not None:
        # (p holds every vehicle of the scenario, in order)
        before = (0.0 if scenario.start_accelerations is None
                  else scenario.start_accelerations[:, None, :])
        change = np.abs(np.diff(a, axis=1, prepend=before))
        jerk = change > lim.jerk_max * scenario.dt * fraction + extra
    middle = p[:, :-1] + 0.5 * scenario.dt * v[:, :-1]
    wall_rows = (middle < lim.position_min + wall) | (middle > lim.position_max - wall)
    return BoxMask(bounds, jerk, wall_rows)


def near_boxes(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray,
               dual: bool = False) -> BoxMask:
    """Boxes worth including from the start: nearly binding at (p, v, a) (more nearly for
    the dual QPs)."""
    size = scenario.limits.position_max - scenario.limits.position_min
    fraction, wall = ((DUAL_NEAR_FRACTION, DUAL_WALL_FRACTION) if dual
                      else (NEAR_FRACTION, WALL_FRACTION))
    return _masks(scenario, p, v, a, fraction, wall * size, 0.0)


def broken_boxes(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray,
                 tolerance: float) -> BoxMask:
    """Boxes that (p, v, a) violate by more than `tolerance`."""
    return _masks(scenario, p, v, a, 1.0, -tolerance, tolerance)
