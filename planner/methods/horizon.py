"""The shortest horizon for a set of rest-to-rest moves: the fewest steps K at which every
move's closed-form straight profile (`planner.scp.first_qp.unit_profile` scaled by the move)
respects the velocity, acceleration and jerk boxes and the scenario's horizon check.

At that K the separation-free first QP is solved in closed form (no vehicle needs the
batched QP), so free-assignment moves stay CAPT's synchronised straight lines.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planner.model.scenario import minimum_transfer_time
from planner.scp.first_qp import BOX_TOLERANCE, unit_profile
from planner.types import FloatArray

__all__ = ["MAX_SEARCH_STEPS", "fewest_steps", "profile_fits", "shortest_steps"]

#: Largest K `shortest_steps` tries before giving up (ValueError).
MAX_SEARCH_STEPS = 20_000


def profile_fits(steps: int, dt: float, reach: FloatArray, velocity_max: FloatArray | None,
                 acceleration_max: FloatArray | None, jerk_max: FloatArray | None) -> bool:
    """Does the unit profile over `steps` steps, scaled by the per-axis distance `reach`,
    respect the boxes (the first and last jerk measured from and to hover) and leave the
    rest-to-rest bound room within the (K - 1) steps the motion has?"""
    _, v, a = unit_profile(steps, dt)
    tol = BOX_TOLERANCE
    if velocity_max is not None and np.any(reach * np.abs(v).max() > velocity_max + tol):
        return False
    if acceleration_max is not None and np.any(reach * np.abs(a).max()
                                               > acceleration_max + tol):
        return False
    if jerk_max is not None:
        da = np.abs(np.diff(a, prepend=0.0)).max() / dt
        if np.any(reach * da > jerk_max + tol):
            return False
    need = minimum_transfer_time(reach, velocity_max, acceleration_max)
    return bool(np.all(need <= (steps - 1) * dt + 1e-9))


def shortest_steps(moves: FloatArray, dt: float, velocity_max: FloatArray | None,
                   acceleration_max: FloatArray | None, jerk_max: FloatArray | None,
                   least: int = 3) -> int:
    """The fewest steps (>= `least`) at which every move (N x 3 displacements, m) fits the
    boxes as a straight rest-to-rest profile (`profile_fits`): the profile's peaks scale
    with the per-axis farthest move, so one check per K covers the fleet. The boxes only
    loosen as K grows, so a doubling search then bisection finds it."""
    reach = np.abs(np.asarray(moves, dtype=float)).max(axis=0) if len(moves) else np.zeros(3)

    def fits(k: int) -> bool:
        return profile_fits(k, dt, reach, velocity_max, acceleration_max, jerk_max)

    found = fewest_steps(fits, max(least, 3), MAX_SEARCH_STEPS)
    if found is None:
        raise ValueError(f"no horizon up to {MAX_SEARCH_STEPS} steps of {dt:g} s fits "
                         f"moves of {reach.tolist()} m within the boxes")
    return found


def fewest_steps(fits: Callable[[int], bool], least: int, most: int) -> int | None:
    """The fewest steps K in [least, most] with `fits(K)`, for a test that only ever turns
    true as K grows: doubling from `least`, then bisection. None when `fits(most)` fails."""
    low, high = least - 1, least
    while not fits(high):
        if high >= most:
            return None
        low, high = high, min(most, 2 * high)
    while high - low > 1:  # fits(high) holds, fits(low) does not (or low < least)
        middle = (low + high) // 2
        if fits(middle):
            high = middle
        else:
            low = middle
    return high
