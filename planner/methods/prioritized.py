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
about moves clear of everything placed before it (`planner.methods.first_guess`; a moving
vehicle's moves carry its start velocity's drift), and its QPs are small and mostly one-sided.
A batch whose SCP does not converge is planned again with the earlier vehicles nearest to it;
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

from planner.methods.first_guess import clear_guess, crosses_one_point
from planner.methods.spacetime import (
    BATCH_OBSTACLE_SEED,
    continued_scp,
    fleet_routes,
    route_segments,
)
from planner.model.fixed import FixedSet, FixedTrajectory
from planner.model.scenario import Scenario
from planner.result import IterationRecord, Progress
from planner.scp.loop import DEFAULT_BATCH, ScpOptions, ScpOutcome, run_scp
from planner.scp.solvers import QPSolver
from planner.types import FloatArray, IntArray

__all__ = ["NOT_CONVERGED", "UNREACHABLE", "PrioritizedOutcome", "batch_size",
           "dominant_motion", "near_fixed", "order_vehicles", "plan_batches"]

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
    options = _batch_options(work, options)
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
    message = _message(len(planned_order), batch, merges, len(deferred))
    joined = ScpOutcome("converged", message, state.p, state.v, state.a, iterations,
                        first_qp)
    return PrioritizedOutcome(joined, planned_order, seconds)


def _batch_options(work: Scenario, options: ScpOptions | None) -> ScpOptions:
    """The SCP options every batch of `work` is planned with."""
    # a batch's QPs are small and mostly one-sided rows, dense in the dual (one vehicle's
    # rows against many fixed ones all couple): the primal measured about twice as fast
    options = dataclasses.replace(options or ScpOptions(), dual=False)
    if work.obstacles:
        options = dataclasses.replace(options, obstacle_seed=BATCH_OBSTACLE_SEED)
    return options


def _message(batches: int, batch: int, merges: int, deferred: int) -> str:
    """What the joined plan says of its batches."""
    return (f"planned in {batches} prioritized batches of up to {batch} vehicles"
            + (f" ({merges} replanned with earlier vehicles)" if merges else "")
            + (f" ({deferred} deferred to the end of the order)" if deferred else "")
            + ", each converged")


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
    sub = sub.with_fixed_set(FixedSet(
        [f.id for f in fixed], others,
        np.concatenate([own.velocities, state.v[moving], np.zeros((len(resting), steps + 1, 3))]),
        np.concatenate([own.accelerations, state.a[moving], np.zeros((len(resting), steps, 3))]),
        np.concatenate([own.margins, np.zeros(planned)]),
        np.concatenate([own.interval_margins, np.zeros((planned, steps))]),
        None if own.deficits is None
        else np.concatenate([own.deficits[group], np.zeros((len(group), planned))], axis=1),
        own.interval_relief))
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
