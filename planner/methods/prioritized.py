"""Prioritized batches: plan a large fleet a batch of vehicles at a time.

The vehicles are ordered (`order_vehicles`) and cut into batches (`batch_size`: single
vehicles in an obstacle-free crowd without a dominant motion, else pairs). Batch k is planned by the
ordinary SCP loop with every vehicle of batches 0..k-1 as a fixed trajectory
(`planner.model.fixed`): its rows keep R from their planned motion over continuous time. The
vehicles of later batches are reserved at their starts (a fixed trajectory resting there for
the whole horizon), so that an earlier vehicle never flies through a start a later one still
occupies (revised prioritized planning, Čáp et al. 2015); a reservation that a batch
vehicle's goal lies on is left out. A fleet that starts in motion (a replan from a flying
state) reserves nothing: a moving vehicle cannot wait where it is, and the braking holds
it could be given block the earlier batches' moves (measured: a random replan of 100
from a quarter of the way in had no feasible first batch). The scenario's own fixed
trajectories (a dropped vehicle) are fixed in every batch. Each batch is first linearised
about moves clear of everything placed before it (`clear_guess`; a moving vehicle's moves
carry its start velocity's drift), and its QPs are small and mostly one-sided. A
batch whose SCP does not converge is planned again with the earlier vehicles nearest to it;
if that fails too it is deferred once to the end of the order (later vehicles waiting at
their starts in its way are then planned, and leave, before it), and a second failure ends
the decomposition (`plan_batches` returns why). The joined plan is verified as a whole
by the caller (`planner.plan`, with `planner.verification.verify`), which plans the whole fleet
instead
when the decomposition ends or the check fails: the guarantee is the verifier's.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.methods.routes import along
from planner.methods.spacetime import (
    BATCH_OBSTACLE_SEED,
    ROUTE_GAP,
    continued_scp,
    depart,
    fleet_routes,
    route_segments,
)
from planner.model.fixed import FixedSet, FixedTrajectory
from planner.model.scenario import Scenario
from planner.result import IterationRecord, Progress
from planner.scp.first_qp import unit_profile, velocity_profile
from planner.scp.loop import DEFAULT_BATCH, ScpOptions, ScpOutcome, run_scp
from planner.scp.solvers import QPSolver
from planner.types import FloatArray, IntArray

__all__ = ["NOT_CONVERGED", "UNREACHABLE", "Placed", "PrioritizedOutcome", "batch_size",
           "clear_guess", "crosses_one_point", "dominant_motion", "near_fixed",
           "order_vehicles", "plan_batches", "polylines", "positions_along"]

#: A fixed trajectory joins a batch's scenario only if it comes within this many R (scaled)
#: of a batch vehicle's straight move at some instant of the horizon (any time: the batch's
#: paths bend). Farther ones get no rows; the joined plan's verification judges them.
REACH = 4.0


@dataclasses.dataclass
class PrioritizedOutcome:
    """The joined trajectories of every batch and what each batch's SCP did."""

    outcome: ScpOutcome
    batches: list[IntArray]
    """The batches in the order they were planned (a deferred one where it succeeded)."""
    batch_seconds: list[float]
    """Each batch's time, its failed attempts before a deferral included."""


#: Why `plan_batches` gave up (the caller then plans the whole fleet and says so).
NOT_CONVERGED = "a batch did not converge, even with its nearest earlier vehicles and deferred"
UNREACHABLE = "a goal cannot be reached around the obstacles"


def dominant_motion(scenario: Scenario) -> FloatArray | None:
    """The unit direction of the fleet's mean move when it is over half the mean move's
    length (a fleet moving as one), else None (crowds crossing a centre, random moves)."""
    move = scenario.goals - scenario.starts
    mean = move.mean(axis=0)
    if float(np.linalg.norm(mean)) > 0.5 * float(np.linalg.norm(move, axis=1).mean()):
        direction: FloatArray | None = mean / np.linalg.norm(mean)
        return direction
    return None


def order_vehicles(scenario: Scenario) -> IntArray:
    """Planning order: a sweep along the fleet's dominant motion, the vehicles whose goals
    lie farthest along it first (they fill the far side before the others arrive and leave
    the near side free); without a dominant motion (crowds crossing a centre, random moves)
    the longest moves first."""
    direction = dominant_motion(scenario)
    if direction is not None:
        return np.argsort(-(scenario.goals @ direction), kind="stable").astype(np.intp)
    length = np.linalg.norm(scenario.goals - scenario.starts, axis=1)
    return np.argsort(-length, kind="stable").astype(np.intp)


def batch_size(scenario: Scenario, asked: int | None = None) -> int:
    """Vehicles per batch: `asked`, else 1 for an obstacle-free fleet without a dominant
    motion (in a crowd crossing a centre a pair's SCP iterates until the slower of two
    unrelated vehicles converges: grid -> sphere 256 1.2-1.3x less CPU a vehicle at a
    time, random 256 1.1x) and DEFAULT_BATCH otherwise (along a dominant motion neighbours
    in the sweep move alike and converge together: sideways 100 1.6x less CPU in pairs;
    forest 50 measured the same either way)."""
    if asked is not None:
        return asked
    if scenario.obstacles or dominant_motion(scenario) is not None:
        return DEFAULT_BATCH
    return 1


def _segment_distance(points: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """(P, S) distances from points (P, 3) to segments a[s]-b[s] (S, 3)."""
    d = b - a
    dd = np.maximum(np.einsum("sc,sc->s", d, d), 1e-12)
    rel = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("psc,sc->ps", rel, d) / dd[None, :], 0.0, 1.0)
    distances: FloatArray = np.linalg.norm(rel - t[..., None] * d[None, :, :], axis=2)
    return distances


def near_fixed(scenario: Scenario, members: IntArray, paths: FloatArray, reach: float,
                routes: dict[int, FloatArray] | None = None) -> IntArray:
    """Indices of the trajectories `paths` (F, K+1, 3) whose samples come within `reach`
    (scaled) of a straight move of `members`, or of its polyline in `routes` (keyed by
    vehicle) where it has one: a route can bend farther than `reach` from the straight
    move."""
    if len(paths) == 0:
        return np.zeros(0, dtype=np.intp)
    scale = scenario.separation_scale
    a, b = route_segments(scenario, members, routes or {})
    a, b = a / scale, b / scale
    f, k = paths.shape[0], paths.shape[1]
    stride = max(1, k // 30)
    samples = paths[:, ::stride] / scale
    flat = samples.reshape(-1, 3)
    near = (_segment_distance(flat, a, b) <= reach).any(axis=1).reshape(f, -1).any(axis=1)
    return np.flatnonzero(near).astype(np.intp)


def plan_batches(work: Scenario, solver: QPSolver, options: ScpOptions | None = None,
                 progress: Progress | None = None,
                 batch: int | None = None, order: IntArray | None = None,
                 cost_share: bool = False) -> PrioritizedOutcome | str:
    """Plan `work` (goals assigned; its own fixed trajectories, start velocities and
    accelerations are kept) batch by batch. A batch whose SCP does not converge is planned
    again together with the earlier vehicles that come closest to its first linearisation
    point (MERGE_ROUNDS times, MERGE_GROWTH more each time); if it still does not, it is
    deferred once to the end of the order (the later vehicles reserved at their starts may
    be what blocks it: planned first, they leave; a fleet in motion reserves nothing, so it
    is not deferred). With `cost_share` each batch stops at its share of `cost_threshold`
    (`planner.options.PlanningOptions.batch_cost_share`). Returns why it gave up
    (NOT_CONVERGED, UNREACHABLE) instead of an
    outcome when a batch fails again or a goal is cut off."""
    n, steps = len(work.vehicles), work.steps
    # a vehicle in motion cannot wait where it is: starts are reserved from rest only
    reserve = not (np.any(work.initial_velocities) or np.any(work.initial_accelerations))
    # a batch's QPs are small and mostly one-sided rows, dense in the dual (one vehicle's
    # rows against many fixed ones all couple): the primal measured about twice as fast
    options = dataclasses.replace(options or ScpOptions(), dual=False)
    if work.obstacles:
        options = dataclasses.replace(options, obstacle_seed=BATCH_OBSTACLE_SEED)
    order = order_vehicles(work) if order is None else order
    batch = batch_size(work, batch)
    batches = [order[s:s + batch] for s in range(0, n, batch)]
    routes: dict[int, FloatArray] = {}
    if work.obstacles:  # every route once for the fleet; an unreachable goal: plan whole
        found = fleet_routes(work)
        if found.unreachable is not None:
            return UNREACHABLE
        routes = found.routes
    state = _State(work, np.repeat(work.starts[:, None, :], steps + 1, axis=1),
                   np.zeros((n, steps + 1, 3)), np.zeros((n, steps, 3)), np.zeros(n, bool),
                   routes, crosses_one_point(work))
    iterations: list[IterationRecord] = []
    seconds: list[float] = []
    first_qp = 0.0
    merges = 0
    queue = list(batches)
    planned_order: list[IntArray] = []
    deferred: set[int] = set()
    spent: dict[int, float] = {}
    number = 0
    while queue:
        members = queue.pop(0)
        began = time.perf_counter()
        later = (np.concatenate(queue) if reserve and queue else np.zeros(0, dtype=np.intp))
        reopened = np.zeros(0, dtype=np.intp)
        tag = _batch_tag(number + 1, number + 1 + len(queue))
        told = None if progress is None else _tagged(progress, tag)
        for attempt in range(MERGE_ROUNDS + 1):
            outcome, guess = _plan_batch(state, members, reopened, later, solver, options,
                                         told, f"#batch{number}" + "+" * attempt,
                                         cost_share)
            iterations.extend(map(tag, outcome.iterations))
            first_qp += outcome.first_qp_seconds
            if outcome.status == "converged" or attempt == MERGE_ROUNDS:
                break
            reopened = _blockers(state, members, reopened, guess,
                                 MERGE_GROWTH * (attempt + 1))
            if reopened.size == 0:
                break
            merges += 1
        key = int(members[0])
        spent[key] = spent.get(key, 0.0) + time.perf_counter() - began
        number += 1
        if outcome.status != "converged":
            if key in deferred or not queue or not reserve:
                return NOT_CONVERGED
            # blocked by later vehicles waiting at their starts: plan it after them
            deferred.add(key)
            queue.append(members)
            continue
        seconds.append(spent.pop(key))
        group = np.concatenate([members, reopened])
        state.p[group], state.v[group], state.a[group] = (
            outcome.positions, outcome.velocities, outcome.accelerations)
        state.planned[group] = True
        planned_order.append(members)
    message = (f"planned in {len(planned_order)} prioritized batches of up to {batch} vehicles"
               + (f" ({merges} replanned with earlier vehicles)" if merges else "")
               + (f" ({len(deferred)} deferred to the end of the order)" if deferred else "")
               + ", each converged")
    joined = ScpOutcome("converged", message, state.p, state.v, state.a, iterations,
                        first_qp)
    return PrioritizedOutcome(joined, planned_order, seconds)


def _batch_tag(batch: int, batches: int) -> Callable[[Any], Any]:
    """An iteration's record (or its `IterationProgress`) labelled as batch `batch` of
    `batches` (`IterationRecord.batch`)."""
    return lambda record: dataclasses.replace(record, batch=batch, batches=batches)


def _tagged(progress: Progress, tag: Callable[[Any], Any]) -> Progress:
    """`progress` given each record labelled by `tag`: batch by batch progress."""
    return lambda record: progress(tag(record))


#: Rounds of replanning a failed batch with the earlier vehicles nearest to it.
MERGE_ROUNDS = 2
#: Earlier vehicles reopened per round (the second round reopens twice as many).
MERGE_GROWTH = 4


@dataclasses.dataclass
class _State:
    """The fleet's trajectories so far; `planned` marks the vehicles already planned."""

    work: Scenario
    p: FloatArray
    v: FloatArray
    a: FloatArray
    planned: NDArray[np.bool_]
    routes: dict[int, FloatArray] = dataclasses.field(default_factory=dict)
    """With obstacles, every vehicle's route polyline (`planner.methods.spacetime.fleet_routes`)."""
    crossing: bool = False
    """Do the fleet's straight moves cross one point (`crosses_one_point`)?"""


def _plan_batch(state: _State, members: IntArray, reopened: IntArray, later: IntArray,
                solver: QPSolver, options: ScpOptions | None,
                progress: Progress | None, suffix: str,
                cost_share: bool = False
                ) -> tuple[ScpOutcome, tuple[FloatArray, FloatArray, FloatArray]]:
    """One batch's SCP: `members` and the `reopened` earlier vehicles planned, the other
    planned vehicles near them and the scenario's own fixed trajectories fixed, the `later`
    vehicles' starts reserved. Returns the outcome (rows of `members` then `reopened`) and
    the first linearisation point."""
    work = state.work
    steps, scale = work.steps, work.separation_scale
    reach = REACH * work.min_separation
    group = np.concatenate([members, reopened]).astype(np.intp)
    earlier = np.flatnonzero(state.planned)
    earlier = earlier[~np.isin(earlier, reopened)]
    # a later vehicle's start that some goal of this batch lies on cannot be reserved
    if len(later):
        goal_gap = np.linalg.norm((work.starts[later][:, None, :]
                                   - work.goals[group][None, :, :]) / scale, axis=2)
        later = later[goal_gap.min(axis=1) >= work.min_separation * 1.05]
    own = work.fixed_set
    fixed: list[FixedTrajectory] = list(work.fixed)
    moving = earlier[near_fixed(work, group, state.p[earlier], reach, state.routes)]
    for j in moving:
        fixed.append(FixedTrajectory(f"~{work.vehicles[j].id}", state.p[j], state.v[j]))
    resting = np.zeros(0, dtype=np.intp)
    if len(later):
        resting = later[near_fixed(work, group, work.starts[later][:, None, :], reach,
                                    state.routes)]
        for j in resting:
            fixed.append(FixedTrajectory(f"~{work.vehicles[j].id}", work.starts[j][None, :]))
    share = len(group) / len(work.vehicles) if cost_share else 1.0
    sub = dataclasses.replace(
        work, name=f"{work.name}{suffix}", vehicles=tuple(work.vehicles[j] for j in group),
        starts=work.starts[group], goals=work.goals[group], fixed=tuple(fixed),
        start_velocities=_rows(work.start_velocities, group),
        start_accelerations=_rows(work.start_accelerations, group),
        cost_threshold=share * work.cost_threshold)
    others = np.concatenate([own.positions, state.p[moving],
                             np.repeat(work.starts[resting][:, None, :], steps + 1, axis=1)])
    # the fixed trajectories' arrays are the plans themselves: no need to resample them
    planned = len(moving) + len(resting)
    sub.__dict__["fixed_set"] = FixedSet(
        [f.id for f in fixed], others,
        np.concatenate([own.velocities, state.v[moving], np.zeros((len(resting), steps + 1, 3))]),
        np.concatenate([own.accelerations, state.a[moving], np.zeros((len(resting), steps, 3))]),
        np.concatenate([own.margins, np.zeros(planned)]),
        np.concatenate([own.interval_margins, np.zeros((planned, steps))]),
        None if own.deficits is None
        else np.concatenate([own.deficits[group], np.zeros((len(group), planned))], axis=1),
        own.interval_relief)
    preset = (state.p[reopened], state.v[reopened], state.a[reopened])
    guess = clear_guess(sub, others, preset,
                        {i: state.routes[int(j)] for i, j in enumerate(members)
                         if int(j) in state.routes}, state.crossing)
    if not state.routes:
        return run_scp(sub, solver, options, progress, guess), guess
    return continued_scp(sub, solver, options, progress, guess), guess


def _rows(values: FloatArray | None, group: IntArray) -> FloatArray | None:
    """`values[group]`, or None (a scenario's optional per-vehicle arrays)."""
    return None if values is None else values[group]


def _blockers(state: _State, members: IntArray, reopened: IntArray,
              guess: tuple[FloatArray, FloatArray, FloatArray], count: int) -> IntArray:
    """`reopened` plus the `count` planned vehicles (not yet reopened) that come closest to
    the batch's first linearisation point at the same instants."""
    scale = state.work.separation_scale
    candidates = np.flatnonzero(state.planned)
    candidates = candidates[~np.isin(candidates, reopened)]
    if candidates.size == 0:
        return reopened
    ours = guess[0][:len(members)] / scale  # (M, K+1, 3)
    theirs = state.p[candidates] / scale  # (C, K+1, 3)
    gap = np.full(len(candidates), np.inf)
    for m in ours:
        gap = np.minimum(gap, np.linalg.norm(theirs - m[None], axis=2).min(axis=1))
    take = candidates[np.argsort(gap, kind="stable")[:count]]
    return np.concatenate([reopened, take]).astype(np.intp)


#: A guess is taken as soon as it keeps this many R from everything placed before it.
GUESS_GAP = 1.3
#: Departure delays tried, as fractions of the horizon.
DELAYS = (0.0, 0.1, 0.2, 0.3)
#: Sideways detours through the move's midpoint tried, in units of R.
DETOURS = (0.0, 1.5, 3.0)
#: In a crowd crossing one point (`crosses_one_point`), where no candidate of DELAYS and
#: DETOURS (four directions) keeps even R, these are tried too: later departures, a wider
#: detour and the four diagonal directions (antipodal sphere 64: no batch replanned with
#: earlier vehicles, against 18 of 64, and 4x less CPU). Elsewhere they cost more than
#: they save (grid -> sphere 256: 1.3-1.5x the CPU, tried where R is not kept).
WIDE_DELAYS = (0.05, 0.15, 0.25, 0.35, 0.4, 0.45, 0.5)
WIDE_DETOURS = (4.5,)


def _pushes(amounts: tuple[float, ...], ways: FloatArray) -> FloatArray:
    """Every amount along every way ((W, 3) unit directions), amount-major: (A W, 3)."""
    return (np.asarray(amounts)[:, None, None] * ways[None]).reshape(-1, 3)


def polylines(scenario: Scenario, vehicle: int, wide: bool = False) -> FloatArray:
    """(C, 3, 3) polylines start -> midpoint -> goal to try, cheapest first: the straight
    move, then its midpoint pushed sideways by each of DETOURS in four directions (`wide`:
    and WIDE_DETOURS, in eight)."""
    s, g = scenario.starts[vehicle], scenario.goals[vehicle]
    move = g - s
    length = float(np.linalg.norm(move))
    axis = move / length if length > 1e-9 else np.array([1.0, 0.0, 0.0])
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    side = np.cross(axis, helper)
    side /= np.linalg.norm(side)
    up = np.cross(side, axis)
    low, high = scenario.limits.position_min, scenario.limits.position_max
    ways = np.stack([side, -side, up, -up])
    pushes = _pushes(DETOURS[1:], ways)
    if wide:  # after the first set: the diagonals, then the wider detours every way
        diagonals = np.stack([side + up, side - up, up - side, -side - up]) / 2**0.5
        pushes = np.concatenate([pushes, _pushes(DETOURS[1:], diagonals),
                                 _pushes(WIDE_DETOURS, np.concatenate([ways, diagonals]))])
    pushes = pushes * scenario.min_separation
    out = np.empty((1 + len(pushes), 3, 3))
    out[:, 0], out[:, 2] = s, g
    out[0, 1] = 0.5 * (s + g)
    out[1:, 1] = np.clip(0.5 * (s + g) + pushes, low, high)
    return out


def positions_along(lines: FloatArray, scenario: Scenario, delay: int) -> FloatArray:
    """(C, K+1, 3) positions along each polyline of `lines` (C, 3, 3), waiting `delay`
    steps, then on the unit profile (as `planner.methods.routes.along`)."""
    phi = np.clip(unit_profile(scenario.steps - delay, scenario.dt)[0], 0.0, 1.0)
    seg = np.diff(lines, axis=1)  # (C, 2, 3)
    seg_len = np.maximum(np.linalg.norm(seg, axis=2), 1e-12)  # (C, 2)
    total = seg_len.sum(axis=1)  # (C,)
    travelled = phi[None, :] * total[:, None]  # (C, T)
    second = travelled > seg_len[:, :1]
    frac = np.where(second, (travelled - seg_len[:, :1]) / seg_len[:, 1:],
                    travelled / seg_len[:, :1])
    frac = np.clip(frac, 0.0, 1.0)
    base = np.where(second[..., None], lines[:, 1:2], lines[:, 0:1])
    step = np.where(second[..., None], seg[:, 1:2], seg[:, 0:1])
    p: FloatArray = base + frac[..., None] * step
    if delay:
        p = np.concatenate([np.repeat(lines[:, :1], delay, axis=1), p], axis=1)
    return p


def crosses_one_point(scenario: Scenario) -> bool:
    """Do most of the fleet's straight moves pass within R of one point, the mean of their
    midpoints (antipodal swaps, grids mirrored through their centre)? Such a crowd needs
    the wide candidates of `clear_guess`."""
    s, g = scenario.starts, scenario.goals
    centre = 0.5 * (s + g).mean(axis=0)
    move = g - s
    t = np.clip(np.einsum("nc,nc->n", centre - s, move)
                / np.maximum(np.einsum("nc,nc->n", move, move), 1e-12), 0.0, 1.0)
    miss = np.linalg.norm((s + t[:, None] * move - centre) / scenario.separation_scale, axis=1)
    return bool(len(miss) > 1 and np.median(miss) < scenario.min_separation)


def clear_guess(scenario: Scenario, others: FloatArray,
                preset: tuple[FloatArray, FloatArray, FloatArray] | None = None,
                routes: dict[int, FloatArray] | None = None, crossing: bool = False
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A first linearisation point for a batch: per vehicle the cheapest candidate (a
    straight or detoured polyline, departing at once or later) that keeps GUESS_GAP R at
    every step from `others` (F, K+1, 3) and from the batch's vehicles placed before it,
    else the one that keeps farthest (with `crossing`, a crowd crossing one point, the wide
    candidates too where none keeps R); the last vehicles keep `preset` (p, v, a) if given
    (earlier vehicles planned again); a vehicle with a polyline in `routes` (around
    obstacles) only tries it, departing at once or later (at rest: `_routed_departure`).
    Rows linearised about a separated point ask the QP for no jump past a fixed vehicle."""
    n, stages = len(scenario.vehicles), scenario.steps + 1
    scale = scenario.separation_scale
    p = np.zeros((n, stages, 3))
    v = np.zeros((n, stages, 3))
    a = np.zeros((n, stages - 1, 3))
    fresh = n
    if preset is not None and len(preset[0]):
        fresh = n - len(preset[0])
        p[fresh:], v[fresh:], a[fresh:] = preset
    placed = Placed(np.concatenate([others / scale, p[fresh:] / scale]))
    need = GUESS_GAP * scenario.min_separation
    drift = _drift(scenario)
    for i in range(fresh):
        lines = polylines(scenario, i)
        chosen = (lines[0], 0)
        if routes and i in routes:
            if scenario.start_velocities is None:
                p[i], v[i], a[i] = _routed_departure(
                    scenario, routes[i], polylines(scenario, i, wide=True), placed)
                placed.add(p[i] / scale)
                continue
            chosen = _route_departure(scenario, routes[i], placed.points, need,
                                      drift[0][i])
        elif len(placed.points):
            best = -np.inf
            tries = [(lines[:1], 0)] + [(lines, int(d * scenario.steps)) for d in DELAYS]
            first = len(tries)
            if crossing:
                wide = polylines(scenario, i, wide=True)
                tries += ([(wide[len(lines):], int(d * scenario.steps)) for d in DELAYS]
                          + [(wide, int(d * scenario.steps)) for d in WIDE_DELAYS])
            for number, (subset, delay) in enumerate(tries):  # the straight move first
                if number == first and best >= scenario.min_separation:
                    break  # R kept: the wide candidates would cost more than they save
                trial = (positions_along(subset, scenario, delay) + drift[0][i]) / scale
                gap = placed.gaps(trial, need)
                clear = np.flatnonzero(gap >= need)
                pick = int(clear[0]) if clear.size else int(np.argmax(gap))
                if clear.size or gap[pick] > best:
                    chosen, best = (subset[pick], delay), float(gap[pick])
                if clear.size:
                    break
        p[i], v[i], a[i] = along(chosen[0], scenario, chosen[1])
        p[i] += drift[0][i]
        v[i] += drift[1][i]
        a[i] += drift[2][i]
        placed.add(p[i] / scale)
    return p, v, a


#: Samples per segment where a detoured polyline's clearance from the obstacles is checked.
CLEARANCE_SAMPLES = 24


def _clear_lines(scenario: Scenario, lines: FloatArray) -> NDArray[np.bool_]:
    """Per polyline of `lines` (C, P, 3): does every sample along it (CLEARANCE_SAMPLES per
    segment) keep the obstacle clearance, and a quarter of it more (the samples are
    apart)? The broad phase (`ObstacleSet.near`) picks the obstacles to measure."""
    s = np.linspace(0.0, 1.0, CLEARANCE_SAMPLES)
    a, b = lines[:, :-1], lines[:, 1:]
    points = (a[:, :, None] + s[None, None, :, None] * (b - a)[:, :, None]).reshape(
        len(lines), -1, 3)
    need = 1.25 * scenario.clearance
    geometry = scenario.obstacle_set
    box, obstacle = geometry.near(points.min(axis=1), points.max(axis=1), need)
    ok = np.ones(len(lines), dtype=bool)
    if box.size == 0:
        return ok
    count = points.shape[1]
    flat = points[box].reshape(-1, 3)
    distance = geometry.signed_distance(flat, np.repeat(obstacle, count)).reshape(-1, count)
    ok[box[(distance < need).any(axis=1)]] = False
    return ok


def _routed_departure(scenario: Scenario, route: FloatArray, lines: FloatArray,
                      placed: Placed) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A routed vehicle's first linearisation point from rest: its route departing at the
    first delay that keeps ROUTE_GAP R from the trajectories placed before it
    (`planner.methods.spacetime.depart`); where none does and the route is the straight move (a
    crowd crossing one opening), the first detour of `lines` (`polylines`) clear of the
    obstacles that does at one of DELAYS or WIDE_DELAYS, else the departure that keeps
    farthest."""
    scale = scenario.separation_scale
    need = ROUTE_GAP * scenario.min_separation
    trial = depart(scenario, route, placed.points)
    if len(route) != 2 or len(placed.points) == 0:
        return trial
    best = float(placed.gaps((trial[0] / scale)[None], need)[0])
    if best >= need:
        return trial
    detours = lines[1:][_clear_lines(scenario, lines[1:])]
    if len(detours) == 0:
        return trial
    chosen: tuple[FloatArray, int] | None = None
    for delay in (int(d * scenario.steps) for d in DELAYS + WIDE_DELAYS):
        gap = placed.gaps(positions_along(detours, scenario, delay) / scale, need)
        pick = int(np.argmax(gap >= need)) if (gap >= need).any() else int(np.argmax(gap))
        if gap[pick] > best:
            chosen, best = (detours[pick], delay), float(gap[pick])
        if best >= need:
            break
    return trial if chosen is None else along(chosen[0], scenario, chosen[1])


def _drift(scenario: Scenario) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(p, v, a) per vehicle that its start velocity adds to a rest-to-rest move (the
    velocity profile scaled by it, as in `straight_moves`: out along it and back, braking):
    zeros for vehicles at rest."""
    n, steps = len(scenario.vehicles), scenario.steps
    if scenario.start_velocities is None:
        return np.zeros((n, steps + 1, 3)), np.zeros((n, steps + 1, 3)), np.zeros((n, steps, 3))
    v0 = scenario.start_velocities[:, None, :]
    psi_p, psi_v, psi_a = velocity_profile(steps, scenario.dt)
    return v0 * psi_p[None, :, None], v0 * psi_v[None, :, None], v0 * psi_a[None, :, None]


#: Steps per coarse box of `Placed.gaps`.
GAP_BLOCK = 10


class Placed:
    """Trajectories placed so far (scaled positions, (F, K+1, 3)) with the boxes of their
    positions over blocks of GAP_BLOCK steps, so that a candidate is compared step by step
    only with those whose box comes near its own in the same block."""

    def __init__(self, points: FloatArray) -> None:
        self.points = points
        self.firsts = np.arange(0, points.shape[1], GAP_BLOCK)
        self.lo, self.hi = self._boxes(points)

    def _boxes(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        if len(points) == 0:
            return np.zeros((0, len(self.firsts), 3)), np.zeros((0, len(self.firsts), 3))
        return (np.minimum.reduceat(points, self.firsts, axis=1),
                np.maximum.reduceat(points, self.firsts, axis=1))

    def add(self, trajectory: FloatArray) -> None:
        lo, hi = self._boxes(trajectory[None])
        self.points = np.concatenate([self.points, trajectory[None]])
        self.lo, self.hi = np.concatenate([self.lo, lo]), np.concatenate([self.hi, hi])

    def gaps(self, trial: FloatArray, need: float) -> FloatArray:
        """Per candidate of `trial` (C, K+1, 3) its smallest distance at the same step to
        a placed trajectory; inf when no box comes within `need` (it then keeps at least
        that)."""
        lo, hi = self._boxes(trial)  # (C, B, 3)
        gap = np.maximum(0.0, np.maximum(lo[:, None] - self.hi[None], self.lo[None] - hi[:, None]))
        cand, other, block = np.nonzero(np.einsum("cfbx,cfbx->cfb", gap, gap) < need * need)
        out = np.full(len(trial), np.inf)
        if cand.size == 0:
            return out
        k = (self.firsts[block][:, None] + np.arange(GAP_BLOCK)[None, :]).reshape(-1)
        cand, other = np.repeat(cand, GAP_BLOCK), np.repeat(other, GAP_BLOCK)
        inside = k < trial.shape[1]
        cand, other, k = cand[inside], other[inside], k[inside]
        diff = trial[cand, k] - self.points[other, k]
        np.minimum.at(out, cand, np.sqrt(np.einsum("rx,rx->r", diff, diff)))
        return out


def _route_departure(scenario: Scenario, route: FloatArray, against: FloatArray,
                     need: float, drift: FloatArray) -> tuple[FloatArray, int]:
    """(route, delay): the first of DELAYS at which the route (plus the vehicle's `drift`,
    (K+1, 3)) keeps `need` from `against` (scaled positions, (F, K+1, 3)) at every step,
    else the one that keeps farthest."""
    best, chosen = -np.inf, (route, 0)
    for delay in (int(d * scenario.steps) for d in DELAYS):
        if len(against) == 0:
            return route, delay
        trial = (along(route, scenario, delay)[0] + drift) / scenario.separation_scale
        gap = float(np.sqrt(np.einsum("fkx,fkx->fk", against - trial[None],
                                      against - trial[None]).min()))
        if gap >= need:
            return route, delay
        if gap > best:
            best, chosen = gap, (route, delay)
    return chosen
