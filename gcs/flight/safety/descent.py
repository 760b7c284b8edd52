"""Is a vehicle's straight descent clear of the others' plans?

When `land_faulty` sends down a vehicle that cannot be steered (its link lost, its estimate
invalid), PX4's Land takes it straight down from where it was last seen, and the others fly
on along their plan. `descent_conflicts` checks that against the plan before anyone flies on:
the descent is taken as the whole vertical column under the vehicle, occupied for as long as
the slowest landing takes (`DESCENT_SPEED_MIN`, plus `SETTLE_S`), and every other vehicle's
planned position over that window (sampled at `RATE_HZ`, the plan's exact motion) must keep
`clearance` from it. Conservative on purpose: a vehicle that passes under the column after the
faulty one has gone lower is still counted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from planner import Plan

__all__ = ["DESCENT_SPEED_MIN", "DescentConflict", "descent_conflicts"]

#: The slowest descent assumed (m/s): below PX4's MPC_LAND_SPEED (0.7) and its crawl speed
#: near the ground (MPC_LAND_CRWL, 0.3).
DESCENT_SPEED_MIN = 0.3
#: Added to the descent's window (s): PX4's land detection and a vehicle drifting at touchdown.
SETTLE_S = 3.0
#: The others' planned positions are sampled this often over the window (Hz).
RATE_HZ = 50.0


@dataclass(frozen=True)
class DescentConflict:
    """Another vehicle whose plan comes within the clearance of the descent column."""

    vehicle: str
    distance: float
    """Its closest approach to the column (m)."""
    flight_time: float
    """When (flight time, s)."""


def descent_conflicts(plan: Plan, faulty: str, position: ArrayLike, flight_time: float,
                      clearance: float, ground: float = 0.0) -> list[DescentConflict]:
    """The other vehicles whose plan from `flight_time` on comes closer than `clearance` to
    the column under `position` (world frame, m) down to `ground`: empty when the descent is
    clear of all of them."""
    x, y, top = (float(c) for c in np.asarray(position, dtype=float).reshape(3))
    top = max(top, ground)
    window = (top - ground) / DESCENT_SPEED_MIN + SETTLE_S
    times = flight_time + np.arange(0.0, window + 1.0 / RATE_HZ, 1.0 / RATE_HZ)
    positions = plan.sample(times).position  # (vehicles, times, 3)
    horizontal = np.hypot(positions[:, :, 0] - x, positions[:, :, 1] - y)
    vertical = positions[:, :, 2] - np.clip(positions[:, :, 2], ground, top)
    distance = np.hypot(horizontal, vertical)
    conflicts = []
    for i, vid in enumerate(plan.scenario.ids):
        if vid == faulty:
            continue
        k = int(np.argmin(distance[i]))
        if distance[i, k] < clearance:
            conflicts.append(DescentConflict(vid, float(distance[i, k]), float(times[k])))
    return conflicts
