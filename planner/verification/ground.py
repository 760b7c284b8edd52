"""Which drones are in the air when, for shows that take off from and land on the ground.

A drone is on the ground over a step when it stands still on the ground (z = 0) for the
whole step: at both ends at z <= `GROUND_TOLERANCE`, velocity zero at both ends, acceleration
zero in between. Separation is checked between two drones over the steps where both are in
the air (`planner.verification.verify` with `ground=True`): a drone parked on its home is not
a drone in the air, and homes may stand closer than R. Measured on the trajectories, not
taken from any claim in a plan file.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.types import FloatArray

__all__ = ["GROUND_TOLERANCE", "airborne", "airborne_spans", "starts_on_the_ground"]

#: Height (m) and speed (m/s) below which a drone counts as standing on the ground.
GROUND_TOLERANCE = 1e-6


def starts_on_the_ground(sequence: Mapping[str, Any] | None) -> bool:
    """Whether a plan's `sequence` block is a show's that takes off from the ground (its
    `ground` block): the plan is then checked with the ground rule."""
    return bool(sequence) and isinstance(sequence, Mapping) and "ground" in sequence


def airborne(p: FloatArray, v: FloatArray, a: FloatArray) -> NDArray[np.bool_]:
    """(N, K): whether each drone is off the ground at some instant of each step."""
    low = p[:, :, 2] <= GROUND_TOLERANCE
    still = np.all(np.abs(v) <= GROUND_TOLERANCE, axis=2)
    parked = (low[:, :-1] & low[:, 1:] & still[:, :-1] & still[:, 1:]
              & np.all(np.abs(a) <= GROUND_TOLERANCE, axis=2))
    moving: NDArray[np.bool_] = ~parked
    return moving


def airborne_spans(p: FloatArray, v: FloatArray, a: FloatArray
                   ) -> list[tuple[int, int, NDArray[np.intp]]]:
    """(first step, end step, drones) of each run of steps over which the same drones are in
    the air; runs with fewer than two drones in the air are left out (no pair to check)."""
    flying = airborne(p, v, a)
    steps = flying.shape[1]
    if steps == 0:
        return []
    changes = np.flatnonzero(np.any(flying[:, 1:] != flying[:, :-1], axis=0)) + 1
    bounds = [0, *changes.tolist(), steps]
    out = []
    for first, end in itertools.pairwise(bounds):
        drones = np.flatnonzero(flying[:, first])
        if len(drones) >= 2:
            out.append((first, end, drones))
    return out
