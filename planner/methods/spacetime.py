"""Space-time seeding of prioritized batches among obstacles.

Every vehicle's route around the obstacles is searched once for the whole fleet
(`fleet_routes`: one connectivity check, Dijkstra per routed vehicle), not again per batch.
A batch vehicle then departs along its route at the first delay that keeps `need` from
every trajectory placed before it at every step (`depart`): the earlier vehicles' planned
motion is a reservation of space over time, and the route waits until it is free (Hönig et
al. 2018: a discrete route clear of the others, then continuous refinement). The batch's
first linearisation point is then clear of the earlier vehicles, and the SCP starts from it
without routing again (`run_scp(..., routed=True)`).
"""

from __future__ import annotations

import numpy as np

from planner.methods.routes import Polylines, Trajectories, along, blocked_vehicles, route_polylines
from planner.model.scenario import Scenario
from planner.result import Progress
from planner.scp.first_qp import straight_moves
from planner.scp.loop import ScpOptions, ScpOutcome, run_scp
from planner.scp.solvers import QPSolver
from planner.types import FloatArray, IntArray

__all__ = ["BATCH_OBSTACLE_SEED", "DELAY_STEPS", "ROUTE_GAP", "continued_scp", "depart",
           "fleet_routes", "route_segments"]

#: Departure delays tried, evenly from none to a third of the horizon.
DELAY_STEPS = 24
#: A route departs once it keeps this many R from everything placed before it. Under R: the
#: rows then order a pair that merely comes close, and every step of delay is one the SCP
#: has to undo, iteration by iteration (forest 100: 1.3 R took twice the iterations of
#: ROUTE_GAP; no delay at all left batches infeasible, replanned with earlier vehicles).
ROUTE_GAP = 1.0
#: A batch's obstacle rows within this many clearances of binding at its linearisation point
#: start each iteration's QP (`ScpOptions.obstacle_seed`; the whole fleet's default is 0.5):
#: a batch's QPs are small, so re-solving them for rows added later costs more than the
#: extra rows (forest 100: 25 % less CPU; the whole-fleet obstacle families were slower).
BATCH_OBSTACLE_SEED = 2.0


def fleet_routes(scenario: Scenario) -> Polylines:
    """A polyline per vehicle of `scenario`: its grid route where its straight move comes
    within the clearance of an obstacle, else start -> goal; or the first vehicle whose goal
    is cut off (`unreachable`, no routes)."""
    blocked = blocked_vehicles(scenario, straight_moves(scenario))
    found = route_polylines(scenario, blocked)
    if found.unreachable is not None:
        return found
    routes = {}
    for i in range(len(scenario.vehicles)):
        points = found.routes.get(i)
        if points is None:
            points = np.stack([scenario.starts[i], scenario.goals[i]])
        keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1)
                               > 1e-9])
        routes[i] = points[keep]
    return Polylines(routes)


def depart(scenario: Scenario, route: FloatArray, against: FloatArray) -> Trajectories:
    """The trajectory along `route` that departs at the first of DELAY_STEPS delays (0 to a
    third of the horizon) keeping ROUTE_GAP R (separation metric) from the scaled positions
    `against` (F, K+1, 3) at every step; if none does, the delay that keeps farthest. A
    route of one point (a vehicle holding in place) rests there: no delay changes it."""
    steps = scenario.steps
    need = ROUTE_GAP * scenario.min_separation
    if len(against) == 0 or len(route) < 2:  # nothing placed, or a vehicle holding in place
        return along(route, scenario, 0)
    scale = scenario.separation_scale
    longest = steps // 3
    delays = np.unique(np.linspace(0, longest, DELAY_STEPS + 1).astype(int))
    best, best_gap = None, -np.inf
    for delay in delays:
        trial = along(route, scenario, int(delay))
        diff = against - (trial[0] / scale)[None]
        gap = float(np.sqrt(np.einsum("fkx,fkx->fk", diff, diff).min()))
        if gap >= need:
            return trial
        if gap > best_gap:
            best, best_gap = trial, gap
    assert best is not None
    return best


def route_segments(scenario: Scenario, members: IntArray, routes: dict[int, FloatArray]
                   ) -> tuple[FloatArray, FloatArray]:
    """The segments (a, b), (S, 3) each, of every member's polyline in `routes`, or of its
    straight move where it has none: what a batch's broad phase measures reach from."""
    a, b = [], []
    for j in members.tolist():
        line = routes.get(j)
        if line is None:
            line = np.stack([scenario.starts[j], scenario.goals[j]])
        a.append(line[:-1])
        b.append(line[1:])
    if not a:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.concatenate(a), np.concatenate(b)


def continued_scp(sub: Scenario, solver: QPSolver, options: ScpOptions | None,
                  progress: Progress | None, guess: Trajectories
                  ) -> ScpOutcome:
    """A routed batch's SCP from `guess` (`run_scp(..., routed=True)`); if it stops at its
    iteration cap still creeping (a departure delay being pulled forward a little per
    iteration), once more from where it stopped, which is nearly converged: far cheaper than
    replanning the batch with earlier vehicles reopened, which creeps the same way. The
    stopping rule is the SCP's own; the two runs' iterations are joined."""
    outcome = run_scp(sub, solver, options, progress, guess, routed=True)
    if outcome.status != "max_iterations":
        return outcome
    again = run_scp(sub, solver, options, progress,
                    (outcome.positions, outcome.velocities, outcome.accelerations),
                    routed=True)
    again.iterations[:0] = outcome.iterations
    again.first_qp_seconds += outcome.first_qp_seconds
    return again
