"""Where the others stop when a vehicle falls silent.

A vehicle unheard for `SILENT_HOLD_S` (`gcs.flight.safety.monitor`) may have lost its link.
If so, it flies on on its last setpoint and stops on its own failsafe, off the plan: a
straight line where the plan curves. The others stop on the plan (the flight clock pauses):
each holds the plan's setpoint of one plan time, and its position controller brings it there
from where it is, overshooting a little (`gcs.flight.replan.cascade`).

`silent_hold` picks that plan time, within `HOLD_WINDOW_S` of now: the one whose stops keep
the most room from the silent vehicle's predicted motion over the next `HORIZON_S` (of those
within `TIE_M` of the most, the nearest to now), so a station that notices the silence late
(a busy machine) does not leave a vehicle stopping on the silent one's line.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from gcs.flight.replan.cascade import STEP_S, follow
from planner import Plan
from planner.types import FloatArray

__all__ = ["CANDIDATE_S", "HOLD_WINDOW_S", "HORIZON_S", "NEAR_M", "TIE_M", "silent_hold"]

#: The hold's plan time is chosen this far (s) either side of the plan time reached.
HOLD_WINDOW_S = 0.5
#: The hold's plan time is tried every this many seconds (at least a streamer tick).
CANDIDATE_S = 0.05
#: The stops are judged over this long (s): until the silent vehicle is declared lost and a
#: landing plan around it takes over, with room to spare.
HORIZON_S = 2.5
#: Only vehicles within this distance (m) of the silent one's predicted motion are judged.
NEAR_M = 5.0
#: A hold within this much (m) of the most room is as good: the nearest to now is taken.
TIE_M = 0.002
#: The silent vehicle's predicted world positions at seconds from now: (T,) -> (T, 3).
Predicted = Callable[[FloatArray], FloatArray]


def silent_hold(plan: Plan, predicted: Predicted, now: float, held: list[str],
                positions: ArrayLike, velocities: ArrayLike, rate: float) -> float:
    """The plan time (s, on `plan`'s clock and the streamer's grid of `rate` Hz) near `now`
    at which the vehicles `held` (ids; their measured world `positions` and `velocities`,
    (N, 3) in that order) keep the most room (separation metric) from the silent vehicle's
    `predicted` motion while they come to their holds."""
    scenario = plan.scenario
    every = max(1.0, round(CANDIDATE_S * rate)) / rate
    offsets = np.arange(-HOLD_WINDOW_S, HOLD_WINDOW_S + every / 2, every)
    ticks = np.unique(np.clip(np.round((now + offsets) * rate), 0,
                              np.floor(scenario.horizon * rate)))
    if ticks.size <= 1 or not held:
        return now
    scale: FloatArray = np.asarray(scenario.separation_scale, dtype=np.float64)
    steps = round(HORIZON_S / STEP_S)
    lost: FloatArray = np.asarray(predicted(STEP_S * np.arange(steps + 1.0)), dtype=np.float64)
    p: FloatArray = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    v: FloatArray = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    centre = lost.mean(axis=0) / scale
    reach = float(np.linalg.norm(lost / scale - centre, axis=1).max()) + NEAR_M
    near = np.linalg.norm(p / scale - centre, axis=1) <= reach
    if not near.any():
        return now
    index = {vid: k for k, vid in enumerate(scenario.ids)}
    rows = [index[vid] for vid, close in zip(held, near, strict=True) if close]
    targets = plan.sample(ticks / rate).position[rows]  # (N, C, 3)
    x, _ = follow(np.repeat(p[near][:, None, :], ticks.size, axis=1),
                  np.repeat(v[near][:, None, :], ticks.size, axis=1), targets, 0.0, steps)
    # each hold's approach (T, N, C, 3) against the silent vehicle's motion (T, 3)
    room: FloatArray = np.linalg.norm((x - lost[:, None, None, :]) / scale,
                                      axis=3).min(axis=(0, 1))
    good = np.flatnonzero(room >= float(room.max()) - TIE_M)
    c = int(good[np.argmin(np.abs(ticks[good] / rate - now))])
    time: float = float(ticks[c]) / rate
    return time
