"""Where the others stop when a vehicle falls silent.

A vehicle unheard for `SILENT_HOLD_S` (`gcs.flight.safety.monitor`) may have lost its link.
If so, it flies on on its last setpoint and stops on its own failsafe, off the plan: a
straight line where the plan curves. The others stop on the plan (the flight clock pauses):
each holds the plan's setpoint of one plan time, and its position controller brings it there
from where it is, overshooting a little (`gcs.flight.replan.cascade`).

`silent_hold` picks that plan time, within `HOLD_WINDOW_S` of now: the one whose stops keep
the most room from the silent vehicle's predicted motion over the next `HORIZON_S` (of those
within `TIE_M` of the most, the nearest to now), so a station that notices the silence late
(a busy machine) does not leave a vehicle stopping on the silent one's line. A vehicle whose
stop still comes nearer than the clearance holds up to `NUDGE_MAX_M` farther from it, where
its way there keeps what it kept from every other held vehicle.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from gcs.flight.replan.cascade import STEP_S, follow
from planner import Plan
from planner.types import FloatArray

__all__ = ["CANDIDATE_S", "HOLD_WINDOW_S", "HORIZON_S", "NEAR_M", "NUDGE_MAX_M", "TIE_M",
           "SilentHold", "silent_hold"]

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
#: The farthest (m) a vehicle's hold is moved off the plan, away from the silent one.
NUDGE_MAX_M = 0.3
#: The nudges tried, as fractions of `NUDGE_MAX_M` (the smallest that keeps the clearance).
_NUDGES = np.linspace(0.1, 1.0, 10)

#: The silent vehicle's predicted world positions at seconds from now: (T,) -> (T, 3).
Predicted = Callable[[FloatArray], FloatArray]


@dataclass(frozen=True)
class SilentHold:
    """Where the others hold: the plan's setpoints of `time`, plus `nudges` (world, m)."""

    time: float
    """Plan time (s on the plan's own clock)."""
    nudges: dict[str, FloatArray] = field(default_factory=dict)
    """Offsets off the plan of the vehicles moved away from the silent one, by id."""


def silent_hold(plan: Plan, predicted: Predicted, now: float, held: list[str],
                positions: ArrayLike, velocities: ArrayLike, rate: float,
                clearance: float) -> SilentHold:
    """Where the vehicles `held` (ids; their measured world `positions` and `velocities`,
    (N, 3) in that order) hold near plan time `now` (on the streamer's grid of `rate` Hz) to
    keep the most room (separation metric) from the silent vehicle's `predicted` motion,
    and at least `clearance` where a nudge off the plan gives it."""
    scenario = plan.scenario
    every = max(1.0, round(CANDIDATE_S * rate)) / rate
    offsets = np.arange(-HOLD_WINDOW_S, HOLD_WINDOW_S + every / 2, every)
    ticks = np.unique(np.clip(np.round((now + offsets) * rate), 0,
                              np.floor(scenario.horizon * rate)))
    if ticks.size <= 1 or not held:
        return SilentHold(now)
    scale: FloatArray = np.asarray(scenario.separation_scale, dtype=np.float64)
    steps = round(HORIZON_S / STEP_S)
    lost: FloatArray = np.asarray(predicted(STEP_S * np.arange(steps + 1.0)), dtype=np.float64)
    p: FloatArray = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    v: FloatArray = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    centre = lost.mean(axis=0) / scale
    reach = float(np.linalg.norm(lost / scale - centre, axis=1).max()) + NEAR_M
    near = np.linalg.norm(p / scale - centre, axis=1) <= reach
    if not near.any():
        return SilentHold(now)
    ids = [vid for vid, close in zip(held, near, strict=True) if close]
    targets = plan.sample(ticks / rate).position[[scenario.ids.index(i) for i in ids]]
    x, _ = follow(np.repeat(p[near][:, None, :], ticks.size, axis=1),
                  np.repeat(v[near][:, None, :], ticks.size, axis=1), targets, 0.0, steps)
    # each hold's approach (T, N, C, 3) against the silent vehicle's motion (T, 3): (N, C)
    rooms: FloatArray = np.linalg.norm((x - lost[:, None, None, :]) / scale, axis=3).min(axis=0)
    room = rooms.min(axis=0)
    good = np.flatnonzero(room >= float(room.max()) - TIE_M)
    c = int(good[np.argmin(np.abs(ticks[good] / rate - now))])
    time = float(ticks[c]) / rate
    nudges = _nudges(x[:, :, c], targets[:, c], p[near], v[near], rooms[:, c], lost, scale,
                     clearance, steps)
    return SilentHold(time, {ids[i]: nudge for i, nudge in nudges.items()})


def _nudges(paths: FloatArray, targets: FloatArray, p: FloatArray, v: FloatArray,
            rooms: FloatArray, lost: FloatArray, scale: FloatArray, clearance: float,
            steps: int) -> dict[int, FloatArray]:
    """For each vehicle (index) whose approach `paths` (T, N, 3) comes nearer than
    `clearance` to `lost`: the smallest horizontal nudge of its target away from the silent
    one's rest that keeps the clearance (or the most room) and keeps from every other held
    vehicle's approach what it kept (or the clearance)."""
    out: dict[int, FloatArray] = {}
    rest = lost[-1]
    for i in np.flatnonzero(rooms < clearance):
        away = targets[i] - rest
        away[2] = 0.0
        length = float(np.linalg.norm(away))
        if length < 1e-6:
            continue
        moves = NUDGE_MAX_M * _NUDGES[:, None] * (away / length)  # (K, 3)
        tried, _ = follow(np.repeat(p[i][None], moves.shape[0], axis=0),
                          np.repeat(v[i][None], moves.shape[0], axis=0),
                          targets[i] + moves, 0.0, steps)  # (T, K, 3)
        gain = np.linalg.norm((tried - lost[:, None, :]) / scale, axis=2).min(axis=0)
        others = np.delete(paths, i, axis=1)  # (T, N - 1, 3)
        kept = np.linalg.norm((paths[:, i:i + 1] - others) / scale, axis=2).min(axis=0)
        near = np.linalg.norm((tried[:, :, None, :] - others[:, None, :, :]) / scale,
                              axis=3).min(axis=0)  # (K, N - 1)
        fair = np.all(near >= np.minimum(kept, clearance), axis=1) & (gain > rooms[i])
        if not fair.any():
            continue
        enough = np.flatnonzero(fair & (gain >= clearance))
        k = int(enough[0]) if enough.size else int(np.flatnonzero(fair)[np.argmax(gain[fair])])
        out[int(i)] = moves[k]
    return out
