"""The scenario of a plan that starts from a flying fleet's state (a landing, a replan).

One builder for both, so a plan made in flight keeps everything of the flight's own
scenario that is not about its start: the workspace and boxes, the step length, the
separation metric, the stopping rule, the obstacles with the flight's own clearance, and
the vehicles whose motion is known (`planner.fixed`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from planner.fixed import FixedTrajectory
from planner.scenario import Scenario
from planner.types import FloatArray

__all__ = ["scenario_from_state"]


def scenario_from_state(base: Scenario, label: str, ids: Sequence[str], p: FloatArray,
                        v: FloatArray, a: FloatArray, goals: FloatArray, *,
                        separation: float, steps: int, max_iterations: int | None = None,
                        fixed: Sequence[FixedTrajectory] = ()) -> Scenario:
    """`base`'s workspace, boxes, metric and obstacles (at `base`'s clearance, whatever
    `separation` is) for vehicles `ids` starting at positions `p`, velocities `v` and
    accelerations `a` (N, 3 each, world ENU) bound for `goals`; named "<base> <label>"."""
    data: dict[str, Any] = {
        "name": f"{base.name} {label}",
        "dt": base.dt,
        "steps": steps,
        "min_separation": separation,
        "separation_scale": base.separation_scale.tolist(),
        "cost_threshold": base.cost_threshold,
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
        data["obstacle_clearance"] = base.clearance
    return Scenario.from_dict(data)
