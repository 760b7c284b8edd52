"""Replanning a flying fleet: from its state at a switch instant to new goals, verified.

`plan_replan` takes every steered vehicle's position, velocity and acceleration at the
switch instant (world frame ENU: the flying plan's exact state there) and its goal (new or
kept), plus the vehicles whose motion is known and not planned (`planner.model.fixed`: a dropped
vehicle braking to a hold or landing, a faulty one on its failsafe), and plans with the same
SCP planner under the base scenario's workspace, boxes, R, obstacles and step length. The
result is verified like every plan: continuous-time separation among the planned vehicles
and from the fixed ones (R + margin), boxes, obstacles, boundary conditions, flyability.

From a verified plan's state, pairs passing each other near R can be held to a hair less
than R on the first step (`planner.methods.landing.first_step_clearance`); the replan then keeps
that (it says which in `Replan.separation`); a vehicle that starts closer than R to a fixed
one keeps what it has from that one alone, growing back to R
(`planner.methods.landing.fixed_start_clearances`). `check_goals` refuses goals a replan could
never reach, naming `goals.<id>`.

Numerics only: the ground station picks the switch instant, streams the plan from it and
flies the dropped vehicles' motions (`gcs.flight.replan.replan`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components

from planner.errors import PlannerError, ScenarioError
from planner.methods.landing import (
    START_SLACK,
    LandingError,
    first_step_clearance,
    fixed_start_clearances,
)
from planner.model.checks import check_vector
from planner.model.fixed import FixedTrajectory
from planner.model.from_state import scenario_from_state
from planner.model.scenario import MAX_STEPS, RANGES, Scenario, minimum_transfer_time
from planner.options import PlanningOptions
from planner.planning import plan
from planner.result import Plan
from planner.scp.first_qp import solve_first_qp
from planner.scp.separation import NEAR_MIN_VEHICLES, close_rows, near_pairs
from planner.scp.solvers import SOLVED, make_solver
from planner.types import FloatArray

__all__ = ["Crowd", "Replan", "ReplanError", "check_goals", "crowd", "plan_replan",
           "replan_horizon", "stop_threshold"]

#: The horizon is this many times what the farthest vehicle needs (stop, then move), plus
#: `HORIZON_EXTRA_S`: room to give way to each other and to the fixed vehicles.
HORIZON_FACTOR = 1.3
HORIZON_EXTRA_S = 1.0
#: Share of the velocity bound a move is timed with (a cruise, not a sprint).
CRUISE_SHARE = 0.6
#: Horizons tried, as multiples of the first, when a plan fails to converge or verify (the
#: last gives room to wait for a fixed vehicle descending through someone's path; a flight
#: starts no attempt after its deadline).
RETRY_FACTORS = (1.0, 1.6, 2.6)
#: A replan's SCP stops once an iteration changes the thrust cost by less than this much per
#: vehicle and step ((m/s^2)^2), or the base's threshold if looser. Every iterate already
#: keeps R (its rows are inner approximations) and the plan is verified whatever the rule;
#: what a replan needs is a verified plan soon, not the last crumbs of thrust. The first
#: iteration's change bounds its distance from the optimum (iteration 0, the
#: separation-free QP, is a relaxation), so a replan stopped there is within that of it.
STOP_COST_PER_STEP = 0.01
#: First horizons a replan may take, as multiples of `replan_horizon`'s: the one whose
#: separation-free moves crowd least (`crowd`), the shortest of those within
#: `CROWD_TOLERANCE` of the least crowded. The timing of the moves decides which of them
#: meet: from a circle swap a quarter of the way in, the moves timed to 1.0 bring all 100
#: vehicles to the centre together (one QP of 100 vehicles, 5 s), timed to 1.4 they meet
#: in groups of at most 11 (1 s). Only a crowd of more than `CROWD_SMALL` vehicles at the
#: first candidate looks further (each look is one closed-form first QP, about 0.03 s for
#: 100 vehicles); a fleet of at most that many never looks.
CROWD_FACTORS = (1.0, 1.2, 1.4)
CROWD_TOLERANCE = 1.25
CROWD_SMALL = 16
#: A replan whose first horizon's crowd (`crowd`) starts its QP with more rows than this is
#: planned in prioritized batches (`planner.methods.prioritized`, the size by the fleet's motion:
#: single vehicles in a random crowd; from the moving state, each
#: batch stopping at its share of the replan's threshold, the joined plan within the
#: threshold of the separation-free optimum), the whole fleet if a batch fails or the joined
#: plan does not verify. A crowd's QP time grows much faster than its rows (random 100 a
#: quarter of the way in, 2,200-2,800 rows: 2.3-9 s of CPU), the batches' with the fleet
#: (about 1 s for 100 vehicles); crowds of up to 840 rows took 0.3-1.2 s whole, 0.55-1.0 s
#: in batches.
CROWD_BATCH_ROWS = 900


class ReplanError(PlannerError):
    """No verified replan: the reason in words (the flight goes on with its plan)."""


@dataclass(frozen=True)
class Replan:
    """A verified replan and how it was made."""

    plan: Plan
    """Converged and verified; vehicles in the order given, starting from the given state."""
    separation: float
    """The separation it keeps among the planned vehicles (m): R, or a hair less where the
    state does not allow R on the first step."""
    seconds: float
    attempts: int


def replan_horizon(base: Scenario, starts: FloatArray, velocities: FloatArray,
                   goals: FloatArray) -> float:
    """Seconds a replan gets: the farthest vehicle's stop and move under the boxes, timed at
    a cruise, with room to spare."""
    lim = base.limits
    move = minimum_transfer_time(goals - starts, lim.velocity_max, lim.acceleration_max)
    cruise = (1.0 if lim.velocity_max is None
              else CRUISE_SHARE * float(lim.velocity_max.min()))
    nominal = np.linalg.norm(goals - starts, axis=1) / cruise
    stop = (np.zeros(len(starts)) if lim.acceleration_max is None
            else np.max(np.abs(velocities) / lim.acceleration_max, axis=1))
    need = max(float(np.max(move.max(axis=1) + 2.0 * stop)), float(np.max(nominal)))
    return HORIZON_FACTOR * need + HORIZON_EXTRA_S


def stop_threshold(base: Scenario, vehicles: int, steps: int) -> float:
    """The cost threshold a replan of `vehicles` over `steps` stops at (see
    `STOP_COST_PER_STEP`): never tighter than `base`'s."""
    return max(base.cost_threshold, STOP_COST_PER_STEP * vehicles * steps)


class Crowd(NamedTuple):
    """The largest group of vehicles linked by close approaches along a scenario's
    separation-free moves: the largest QP the first SCP iteration starts with."""

    vehicles: int
    """Its vehicles (all of them when the separation-free QP has no solution)."""
    rows: int
    """Its close approaches (pair and step interval closer than R; 0 when the
    separation-free QP has no solution): a measure of its first QP's size, which seeds
    rows at these intervals and around them."""


def crowd(spec: Scenario, solver: str | None = None) -> Crowd:
    """The largest group linked by close approaches (closer than R over a step) along
    `spec`'s separation-free moves (its first QP), see `Crowd`."""
    first = solve_first_qp(spec, make_solver(solver))
    n = len(spec.vehicles)
    if first.status != SOLVED:
        return Crowd(n, 0)
    lin = (first.positions, first.velocities, first.accelerations)
    scale, separation = spec.separation_scale, spec.min_separation
    near = near_pairs(*lin, spec.dt, scale, separation) if n >= NEAR_MIN_VEHICLES else None
    pairs, _ = close_rows(first.positions, scale, separation, True, near)
    if len(pairs) == 0:
        return Crowd(0, 0)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs.i, pairs.j)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    involved = np.unique(np.concatenate([pairs.i, pairs.j]))
    sizes = np.bincount(label[involved])
    largest = int(np.argmax(sizes))
    return Crowd(int(sizes[largest]), int(np.count_nonzero(label[pairs.i] == largest)))


def check_goals(base: Scenario, goals: Mapping[str, ArrayLike],
                others: Mapping[str, ArrayLike]) -> dict[str, FloatArray]:
    """The new `goals` {id: [x, y, z]} as arrays, each inside the workspace, clear of the
    obstacles, and at least R (separation metric) from every other goal (new ones and the
    kept goals `others`). Raises `ScenarioError` naming ``goals.<id>``."""
    lim = base.limits
    out: dict[str, FloatArray] = {}
    for vid, raw in goals.items():
        where = f"goals.{vid}"
        point = check_vector(list(raw) if isinstance(raw, np.ndarray) else raw, where)
        outside = (point < lim.position_min) | (point > lim.position_max)
        if outside.any():
            axis = int(np.argmax(outside))
            raise ScenarioError(where, f"{point.tolist()} lies outside the workspace on axis "
                                       f"{'xyz'[axis]} [{lim.position_min[axis]:g}, "
                                       f"{lim.position_max[axis]:g}]")
        if base.obstacles:
            geometry = base.obstacle_set
            distance = geometry.signed_distance(np.repeat(point[None], len(base.obstacles), 0),
                                                np.arange(len(base.obstacles)))
            o = int(np.argmin(distance))
            if distance[o] < base.clearance:
                raise ScenarioError(where, f"{point.tolist()} lies inside obstacle "
                                           f"{base.obstacles[o].id!r} (clearance "
                                           f"{base.clearance:g} m)")
        out[vid] = point
    everyone = {**{k: np.asarray(v, dtype=float) for k, v in others.items()
                   if k not in out}, **out}
    names = list(everyone)
    if len(names) >= 2:
        points = np.array([everyone[k] for k in names]) / base.separation_scale
        for vid, point in out.items():
            d = np.linalg.norm(points - point / base.separation_scale, axis=1)
            d[names.index(vid)] = math.inf
            j = int(np.argmin(d))
            if d[j] < base.min_separation:
                raise ScenarioError(f"goals.{vid}",
                                    f"is {d[j]:.3f} m from the goal of {names[j]!r}, closer "
                                    f"than min_separation {base.min_separation:g} m")
    return out


def plan_replan(base: Scenario, ids: Sequence[str], positions: ArrayLike,
                velocities: ArrayLike, accelerations: ArrayLike, goals: ArrayLike, *,
                fixed: Sequence[FixedTrajectory] = (), min_horizon: float = 0.0,
                deadline: float | None = None, solver: str | None = None) -> Replan:
    """A verified plan for vehicles `ids` from their state (N, 3 each) to `goals` (N, 3),
    keeping R from each other and R + margin from `fixed`, under `base`'s workspace, boxes,
    obstacles and step length (see the module).

    min_horizon: the plan lasts at least this long (s), e.g. what the flying plan had left.
    deadline: a `time.perf_counter()` instant after which no further attempt starts.
    Raises `ReplanError` when no verified plan was found, for whatever reason.
    """
    began = time.perf_counter()
    lim = base.limits
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    v = np.asarray(velocities, dtype=float).reshape(-1, 3)
    a = np.asarray(accelerations, dtype=float).reshape(-1, 3)
    g = np.asarray(goals, dtype=float).reshape(-1, 3)
    names = list(ids)
    if not len(p) == len(v) == len(a) == len(g) == len(names) or len(p) == 0:
        raise ReplanError("positions, velocities, accelerations, goals and ids must agree "
                          "in length")
    if not all(np.isfinite(x).all() for x in (p, v, a, g)):
        raise ReplanError("the fleet's state or goals are not finite")
    # A state a hair outside the boxes (rounding) is planned from the nearest one inside.
    p = np.clip(p, lim.position_min, lim.position_max)
    if lim.velocity_max is not None:
        v = np.clip(v, -lim.velocity_max, lim.velocity_max)
    if lim.acceleration_max is not None:
        a = np.clip(a, -lim.acceleration_max, lim.acceleration_max)
    try:  # a vehicle already closer than R to a fixed one: that pair ramps back to R
        fixed = fixed_start_clearances(p, v, a, names, fixed, base)
    except LandingError as exc:
        raise ReplanError(str(exc)) from exc
    clearance = first_step_clearance(p, v, a, base)
    separation = base.min_separation
    if clearance < separation * (1.0 + START_SLACK):
        separation = min(separation, clearance) - START_SLACK * separation
    if not separation >= RANGES["min_separation"][0]:
        raise ReplanError(f"two vehicles are too close to replan: the first step keeps "
                          f"{max(clearance, 0.0):.3f} m")
    horizon = max(min_horizon, replan_horizon(base, p, v, g),
                  max(((len(f) - 1) * base.dt for f in fixed), default=0.0))
    specs: dict[int, Scenario] = {}

    def scenario(length: float) -> Scenario:
        steps = min(MAX_STEPS, max(3, math.ceil(length / base.dt)))
        if steps not in specs:
            specs[steps] = scenario_from_state(
                base, "replan", names, p, v, a, g, separation=separation, steps=steps,
                fixed=fixed, cost_threshold=stop_threshold(base, len(names), steps))
        return specs[steps]

    failures: list[str] = []
    try:
        factor, crowded = _least_crowded(scenario, horizon, solver)
        horizon *= factor
        for attempts, factor in enumerate(RETRY_FACTORS, start=1):
            if deadline is not None and attempts > 1 and time.perf_counter() > deadline:
                break
            spec = scenario(factor * horizon)
            batches = crowded.rows > CROWD_BATCH_ROWS
            result = plan(spec, solver=solver,
                          options=PlanningOptions(batch_cost_share=batches),
                          method="prioritized" if batches else "whole")
            if result.ok:
                return Replan(result, separation, time.perf_counter() - began, attempts)
            failures.append(f"{spec.horizon:.1f} s: {'; '.join(result.problems())}")
    except ScenarioError as exc:  # a goal or start the scenario refuses: no retry helps
        raise ReplanError(f"cannot replan: {exc}") from exc
    except (PlannerError, ValueError, ArithmeticError) as exc:
        raise ReplanError(f"cannot replan: {exc}") from exc
    raise ReplanError("no verified replan (" + " | ".join(failures) + ")")


def _least_crowded(scenario: Callable[[float], Scenario], horizon: float,
                   solver: str | None) -> tuple[float, Crowd]:
    """The factor of `CROWD_FACTORS` the first attempt takes (see there), and the crowd
    there (`crowd`; none when it was not measured, a fleet of at most `CROWD_SMALL`)."""
    if len(scenario(horizon).vehicles) <= CROWD_SMALL:  # no crowd can be larger
        return CROWD_FACTORS[0], Crowd(0, 0)
    first = crowd(scenario(horizon), solver)
    if first.vehicles <= CROWD_SMALL:
        return CROWD_FACTORS[0], first
    crowds = [first] + [crowd(scenario(f * horizon), solver) for f in CROWD_FACTORS[1:]]
    least = min(c.vehicles for c in crowds)
    return next((f, c) for f, c in zip(CROWD_FACTORS, crowds, strict=True)
                if c.vehicles <= CROWD_TOLERANCE * least)
