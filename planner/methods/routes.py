"""Route search that seeds SCP around obstacles, and the early verdict on unreachable goals.
The grid the routes are searched on is `planner.methods.route_grid`.

Linearised about a straight line through a wall, SCP's planes push the path back where it
came from and it stalls. So before the first SCP iteration every vehicle whose initial
trajectory comes within the clearance of an obstacle gets a route: a shortest path on a
3-D grid over the workspace (26 neighbours, Euclidean weights, scipy's Dijkstra), shortened
by dropping waypoints while the straight segment stays in free cells, and time-parametrised
with the minimum-thrust rest-to-rest profile of `planner.scp.first_qp`. That is the point the
first iteration is linearised about (Hönig et al. 2018: discrete route, continuous
refinement).

Two occupancy grids are built from the cells' signed distance to the nearest obstacle:

- for routing, a cell is blocked when its centre is within clearance + a quarter cell;
- for the verdict, only when the whole cell lies within the clearance (centre distance
  <= clearance - half its diagonal; the distance is 1-Lipschitz). Every continuous free path
  passes through cells that are free in that grid, in 26-connected order, so a start and
  goal in different components of it are truly disconnected: the plan ends `infeasible` at
  once, naming the vehicle and the obstacles bordering both sides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from planner.methods.route_grid import Grid, build_grid
from planner.model.obstacles import describe
from planner.model.scenario import Scenario
from planner.scp.first_qp import unit_profile
from planner.scp.obstacle_rows import ObstacleRows, chord_nearest
from planner.types import BoolArray, FloatArray, IntArray

__all__ = ["Polylines", "RouteSeed", "along", "holders", "holding", "route_polylines",
           "seed_routes"]

Trajectories = tuple[FloatArray, FloatArray, FloatArray]

#: A routed vehicle departs later only while it comes closer than this (in units of R) to
#: a vehicle already placed: enough to order vehicles that share a corridor (rows about two
#: coincident points cannot), while a pair merely closer than R is left to the rows (a
#: delay the QP then undoes costs more iterations than it saves).
STAGGER_GAP = 0.5
#: Sources per Dijkstra call (bounds its (sources, cells) output).
DIJKSTRA_BATCH = 16


@dataclass(frozen=True)
class RouteSeed:
    """The first linearisation point with routes, or why a goal cannot be reached."""

    guess: Trajectories
    routed: tuple[int, ...]
    """Vehicles given a route."""
    unreachable: str | None = None
    """For an unreachable goal: the message naming the vehicle and the obstacles."""
    vehicle: int = -1
    """For an unreachable goal: that vehicle's index (-1 otherwise)."""


def holders(scenario: Scenario) -> IntArray:
    """Vehicles that hold in place (goal = start, from rest): for the others' route search
    they are obstacles, which no delay gets past and which the obstacles may pin (a holder
    in the gap between two trees is no way through, however the rows push)."""
    still = np.all(scenario.goals == scenario.starts, axis=1)
    if scenario.start_velocities is not None:
        still &= ~np.any(scenario.start_velocities != 0.0, axis=1)
    return np.flatnonzero(still).astype(np.intp)


def _near_holders(scenario: Scenario, points: FloatArray, planar: bool = False) -> BoolArray:
    """Per point of `points` (..., 3): within R (separation metric; horizontally only on a
    `planar` grid, where a cell stands for every height) of a vehicle holding in place."""
    held = scenario.starts[holders(scenario)]
    near = np.zeros(points.shape[:-1], dtype=bool)
    scale = scenario.separation_scale
    axes = slice(0, 2) if planar else slice(0, 3)
    for h in held:
        d = ((points - h) / scale)[..., axes]
        near |= np.einsum("...c,...c->...", d, d) < scenario.min_separation ** 2
    return near


def blocked_vehicles(scenario: Scenario, lin: Trajectories) -> IntArray:
    """Vehicles whose trajectory `lin` comes within the clearance of an obstacle (checked on
    the chords between steps), or at a step within R of a vehicle holding in place."""
    rows = ObstacleRows(scenario)
    t = rows.near(lin[0], lin[1], 0.0)
    hold = holders(scenario)
    found = np.zeros(0, dtype=np.intp)
    if hold.size:
        near = np.asarray(_near_holders(scenario, lin[0]).any(axis=1), dtype=bool)
        near[hold] = False
        found = np.flatnonzero(near)
    if len(t) == 0:
        return found.astype(np.intp)
    a, b = lin[0][t.vehicle, t.k], lin[0][t.vehicle, t.k + 1]
    q = chord_nearest(rows.geometry, a, b, t.obstacle)
    close = rows.geometry.signed_distance(q, t.obstacle) < scenario.clearance
    return np.union1d(np.unique(t.vehicle[close]), found).astype(np.intp)


def _cutting(grid: Grid, free: BoolArray, labels: IntArray, start: int, goal: int
             ) -> list[int]:
    """Obstacles of the blocked cells next to both the start's and the goal's component."""
    shape = grid.shape
    lab = labels.reshape(shape)
    blocked = ~free.reshape(shape)
    sides = []
    for component in (labels[start], labels[goal]):
        region = lab == component
        grown = region.copy()
        for axis in range(3):
            for shift in (-1, 1):
                grown |= np.roll(region, shift, axis=axis)
        grown &= blocked
        sides.append(set(grid.nearest.reshape(shape)[grown].tolist()))
    both = sides[0] & sides[1]
    return sorted(both or sides[0])


def _shortcut(grid: Grid, free: BoolArray, points: FloatArray) -> FloatArray:
    """Drops waypoints while the straight segment between the kept ones stays in free
    cells (sampled every quarter cell): greedy, farthest visible waypoint first."""
    kept = [0]
    i = 0
    while i < len(points) - 1:
        later = np.arange(i + 1, len(points))
        clear = _segments_free(grid, free, np.repeat(points[i:i + 1], len(later), axis=0),
                               points[later])
        clear[0] = True  # the next waypoint is always reachable along the grid path
        i = int(later[np.flatnonzero(clear).max()])
        kept.append(i)
    return points[kept]


def _climb(points: FloatArray) -> FloatArray:
    """Heights from the first point's to the last's, in proportion to the horizontal
    distance travelled along `points`."""
    run = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points[:, :2], axis=0),
                                                          axis=1))])
    share = run / run[-1] if run[-1] > 1e-12 else np.linspace(0.0, 1.0, len(points))
    heights: FloatArray = points[0, 2] + share * (points[-1, 2] - points[0, 2])
    return heights


def _segments_free(grid: Grid, free: BoolArray, a: FloatArray, b: FloatArray) -> BoolArray:
    """Per segment [a, b] ((S, 3) each): every sample (a quarter cell apart) in a free cell."""
    step = 0.25 * float(grid.spacing.min())
    samples = int(np.ceil(float(np.linalg.norm(b - a, axis=1).max(initial=0.0)) / step)) + 1
    s = np.linspace(0.0, 1.0, samples)
    points = a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]
    inside = free[grid.cell_of(points.reshape(-1, 3))].reshape(len(a), samples)
    return np.asarray(inside.all(axis=1), dtype=bool)


def _toward_line(grid: Grid, free: BoolArray, points: FloatArray) -> FloatArray:
    """Moves each inner waypoint toward the vehicle's straight line (start to goal) as far as
    its two segments stay free (trying all, 3/4, 1/2, 1/4 of the way). Grid paths snap to
    cell centres, so neighbouring vehicles' routes would share waypoints (and altitudes);
    pulled toward their own lines they keep their lanes and heights where the obstacles
    allow."""
    out = points.copy()
    start, goal = points[0], points[-1]
    line = goal - start
    length2 = max(float(line @ line), 1e-12)
    for i in range(1, len(out) - 1):
        foot = start + np.clip((out[i] - start) @ line / length2, 0.0, 1.0) * line
        for alpha in (1.0, 0.75, 0.5, 0.25):
            trial = out[i] + alpha * (foot - out[i])
            ok = _segments_free(grid, free, np.stack([out[i - 1], trial]),
                                np.stack([trial, out[i + 1]]))
            if ok.all():
                out[i] = trial
                break
    return out


def holding(point: FloatArray, steps: int) -> Trajectories:
    """The trajectory resting at `point` for `steps` steps: a vehicle whose goal is its
    start."""
    return (np.repeat(np.asarray(point, dtype=np.float64)[None], steps + 1, axis=0),
            np.zeros((steps + 1, 3)), np.zeros((steps, 3)))


def along(points: FloatArray, scenario: Scenario, delay: int = 0) -> Trajectories:
    """A trajectory along the polyline `points` that waits `delay` steps at the start, then
    moves rest to rest on the minimum-thrust unit profile of the remaining steps (the
    separation-free QP's own timing, so the first QP's solution stays near the routes in
    time: measured 1.5-2x faster than a minimum-jerk timing on the forest family). A
    polyline of no length (a vehicle that holds in place) rests at its point throughout."""
    seg = np.diff(points, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = float(cum[-1])
    if total <= 0.0:
        return holding(points[0], scenario.steps)
    phi_p, phi_v, phi_a = unit_profile(scenario.steps - delay, scenario.dt)
    s = np.clip(phi_p, 0.0, 1.0) * total
    piece = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = (s - cum[piece]) / np.maximum(seg_len[piece], 1e-12)
    p = points[piece] + frac[:, None] * seg[piece]
    p[0], p[-1] = points[0], points[-1]
    tangent = seg / np.maximum(seg_len, 1e-12)[:, None]
    v = tangent[piece] * (total * phi_v)[:, None]
    a = tangent[piece[:-1]] * (total * phi_a)[:, None]
    v[0], v[-1] = 0.0, 0.0
    if delay:
        p = np.vstack([np.repeat(points[:1], delay, axis=0), p])
        v = np.vstack([np.zeros((delay, 3)), v])
        a = np.vstack([np.zeros((delay, 3)), a])
    return p, v, a


def _stagger(scenario: Scenario, guess: Trajectories, routes: dict[int, FloatArray]
             ) -> Trajectories:
    """Delays routed vehicles' departures, one by one, until each is STAGGER_GAP R away (at
    the steps, in the separation metric) from every vehicle already placed: routes of
    neighbouring vehicles often share the shortest corridor, and rows linearised about two
    vehicles at one point cannot order them along it. Up to a third of the horizon; where
    no delay separates a vehicle, the one that keeps it farthest from the others."""
    p, v, a = (x.copy() for x in guess)
    scale, separation = scenario.separation_scale, scenario.min_separation
    placed = np.ones(len(p), dtype=bool)
    placed[list(routes)] = False
    longest = scenario.steps // 3
    for vehicle, points in routes.items():
        others = np.flatnonzero(placed)
        best, best_gap = None, -np.inf
        for delay in range(0, longest + 1, max(1, longest // 30)):
            trial = along(points, scenario, delay)
            if len(others) == 0:
                best = trial
                break
            gap = float(np.min(np.linalg.norm((p[others] - trial[0][None]) / scale, axis=2)))
            if gap > best_gap:
                best, best_gap = trial, gap
            if gap >= STAGGER_GAP * separation:
                break
        assert best is not None
        p[vehicle], v[vehicle], a[vehicle] = best
        placed[vehicle] = True
    return p, v, a


@dataclass(frozen=True)
class Polylines:
    """Route polylines (start, waypoints, goal) per routed vehicle, or why a goal cannot be
    reached."""

    routes: dict[int, FloatArray]
    unreachable: str | None = None
    vehicle: int = -1


def route_polylines(scenario: Scenario, blocked: IntArray) -> Polylines:
    """A shortened grid route around the obstacles for each vehicle of `blocked`, or the
    first of them whose goal is cut off. One connectivity check, one search tree and one
    Dijkstra call per DIJKSTRA_BATCH vehicles, however many are routed."""
    if blocked.size == 0:
        return Polylines({})
    grid = build_grid(scenario)
    c = scenario.clearance
    starts, goals = scenario.starts[blocked], scenario.goals[blocked]

    sure = ~(grid.distance <= c - grid.half_diagonal)  # free unless wholly within clearance
    _, labels = connected_components(grid.graph(sure), directed=False)
    s_cell, g_cell = grid.cell_of(starts), grid.cell_of(goals)
    cut = np.flatnonzero(labels[s_cell] != labels[g_cell])
    if cut.size:
        index = int(blocked[cut[0]])
        obstacles = _cutting(grid, sure, labels, int(s_cell[cut[0]]), int(g_cell[cut[0]]))
        names = describe([scenario.obstacles[o].id for o in obstacles])
        message = (f"vehicles[{index}] ({scenario.vehicles[index].id!r}) cannot reach its goal: "
                   f"no free path from its start keeps the clearance {c:g} m; obstacles "
                   f"{names} cut it off")
        return Polylines({}, message, index)

    free = grid.distance >= c + 0.25 * float(grid.spacing.min())
    routes: dict[int, FloatArray] = {}
    centres = grid.centres
    pending = list(range(len(blocked)))
    masks = [free, sure]  # the optimistic grid where a gap is under a cell
    if holders(scenario).size:  # around the vehicles holding in place first, if a way is
        away = ~_near_holders(scenario, centres, grid.planar)
        masks = [free & away, sure & away, *masks]
    for route_free in masks:
        todo, pending = np.array(pending, dtype=np.intp), []
        graph = grid.graph(route_free)
        free_idx = np.flatnonzero(route_free)
        tree = cKDTree(centres[free_idx])
        src = free_idx[tree.query(starts[todo])[1]]
        dst = free_idx[tree.query(goals[todo])[1]]
        for lo in range(0, len(todo), DIJKSTRA_BATCH):
            batch = slice(lo, lo + DIJKSTRA_BATCH)
            dist, pred = dijkstra(graph, indices=src[batch], return_predecessors=True)
            for row, n in enumerate(todo[batch]):
                target = int(dst[lo + row])
                if not np.isfinite(dist[row, target]):
                    pending.append(n)
                    continue
                path = [target]
                while path[-1] != src[lo + row]:
                    path.append(int(pred[row, path[-1]]))
                waypoints = np.vstack([starts[n], centres[path[::-1]], goals[n]])
                if grid.planar:  # the cells' centres are mid-height: climb evenly instead
                    waypoints[:, 2] = _climb(waypoints)
                routes[int(blocked[n])] = _toward_line(
                    grid, route_free, _shortcut(grid, route_free, waypoints))
        if not pending:
            break
    return Polylines(routes)


def seed_routes(scenario: Scenario, lin: Trajectories) -> RouteSeed:
    """Routes around the obstacles for every vehicle whose `lin` comes within the clearance
    of one (the others keep `lin`), or the first vehicle whose goal is cut off."""
    blocked = blocked_vehicles(scenario, lin)
    if blocked.size == 0:
        return RouteSeed(lin, ())
    found = route_polylines(scenario, blocked)
    if found.unreachable is not None:
        return RouteSeed(lin, (), found.unreachable, found.vehicle)
    return RouteSeed(_stagger(scenario, lin, found.routes), tuple(sorted(found.routes)))
