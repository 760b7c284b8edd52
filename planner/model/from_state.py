"""The scenario of a plan that starts from a flying fleet's state (a landing, a replan).

One builder for both, so a plan made in flight keeps everything of the flight's own
scenario that is not about its start: the workspace and boxes, the step length, the
separation metric, the stopping rule, the obstacles with the flight's own clearance, and
the vehicles whose motion is known (`planner.model.fixed`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from planner.model.fixed import FixedTrajectory
from planner.model.obstacles import CLEARANCE_RANGE
from planner.model.scenario import Scenario
from planner.types import FloatArray

__all__ = ["START_SLACK", "scenario_from_state", "start_clearance"]

#: Where a vehicle starts within this fraction of the clearance of an obstacle, the plan
#: keeps what it has less this fraction (as `planner.methods.landing.START_SLACK` for R).
START_SLACK = 0.01


def scenario_from_state(base: Scenario, label: str, ids: Sequence[str], p: FloatArray,
                        v: FloatArray, a: FloatArray, goals: FloatArray, *,
                        separation: float, steps: int, max_iterations: int | None = None,
                        cost_threshold: float | None = None,
                        fixed: Sequence[FixedTrajectory] = ()) -> Scenario:
    """`base`'s workspace, boxes, metric and obstacles (at `base`'s clearance, whatever
    `separation` is) for vehicles `ids` starting at positions `p`, velocities `v` and
    accelerations `a` (N, 3 each, world ENU) bound for `goals`; named "<base> <label>".
    max_iterations, cost_threshold: the SCP's stopping rule when not `base`'s."""
    data: dict[str, Any] = {
        "name": f"{base.name} {label}",
        "dt": base.dt,
        "steps": steps,
        "min_separation": separation,
        "separation_scale": base.separation_scale.tolist(),
        "cost_threshold": base.cost_threshold if cost_threshold is None else cost_threshold,
        "max_iterations": base.max_iterations if max_iterations is None else max_iterations,
        "limits": base.limits.to_dict(),
        "vehicles": [
            {"id": vid, "start": p[n].tolist(), "goal": goals[n].tolist(),
             "start_velocity": v[n].tolist(), "start_acceleration": a[n].tolist()}
            for n, vid in enumerate(ids)
        ],
    }
    if fixed:
        data["fixed"] = [f.to_dict() for f in fixed]
    if base.obstacles:
        data["obstacles"] = [o.to_dict() for o in base.obstacles]
        data["obstacle_clearance"] = start_clearance(base, p)
    return Scenario.from_dict(data)


def start_clearance(base: Scenario, p: FloatArray) -> float:
    """The obstacle clearance a plan from positions `p` (N, 3) keeps: `base`'s, or, where a
    vehicle is nearer an obstacle than that (a plan's own state at its closest, within the
    verification's tolerance, or a vehicle measured off its plan), what it has less
    `START_SLACK` of the clearance: a flying vehicle cannot be put back outside in no time.
    (A state inside an obstacle keeps the base's clearance, which the scenario refuses.)"""
    clearance = base.clearance
    geometry = base.obstacle_set
    n, m = len(p), len(geometry)
    if n == 0 or m == 0:
        return clearance
    nearest = float(geometry.signed_distance(np.repeat(p, m, axis=0),
                                             np.tile(np.arange(m), n)).min())
    if nearest >= clearance * (1.0 + START_SLACK):
        return clearance
    reduced = min(clearance, nearest) - START_SLACK * clearance
    return reduced if reduced >= CLEARANCE_RANGE[0] else clearance
