"""Plans this ground station does not fly: a show's that takes off from or lands on the ground.

The executor arms each vehicle at its home, climbs it to the plan's start, streams the plan in
the air and lands it after the goals itself (`gcs.flight.run.executor`). A show planned with
`takeoff` / `landing` (`planner.methods.ground`) starts and ends parked on the ground, its own
takeoff waves and landing legs part of the trajectories: flown here, the executor's climb would
come on top of the plan's and its waves would not be flown as planned. Such a plan is refused
before anything is armed, with the fix: a show controller flies its `.skyc`.
"""

from __future__ import annotations

from planner import Plan
from planner.verification.ground import GROUND_TOLERANCE, airborne, starts_on_the_ground

__all__ = ["GROUND_FIX", "ground_refusal"]

#: What to do instead, the same words from the CLI and the REST API.
GROUND_FIX = ("export it as a .skyc for a show controller (fleetplan export PLAN.json "
              "--format skyc -o show.skyc, or the mission's show.skyc from the service), or "
              "plan the sequence without takeoff and landing to fly it here (the ground "
              "station takes off to the first formation and lands after the last by itself)")


def ground_refusal(plan: Plan) -> str | None:
    """Why `plan` cannot be flown by this ground station because it starts or ends on the
    ground (its `sequence.ground` block, or a drone parked at z <= 0 in its trajectories);
    None for a plan flown in the air. Only drones that reach z <= 0 are looked at closer, so
    a plan in the air costs one pass over its heights, no copy of its trajectories."""
    if starts_on_the_ground(plan.sequence):
        return (f"refusing to fly the plan: it is a show that takes off from and lands on the "
                f"ground; {GROUND_FIX}")
    for track in plan.vehicles:
        if track.position[:, 2].min() > GROUND_TOLERANCE:
            continue
        parked = ~airborne(track.position[None], track.velocity[None], track.acceleration[None])
        if parked.any():
            return (f"refusing to fly the plan: vehicle {track.id} stands on the ground "
                    f"(z <= 0) in it; {GROUND_FIX}")
    return None
