"""Landing plans: from a flying fleet's state to touchdown points, planned and verified.

Long: one algorithm: touchdown points, the landing plan and its escape move.

A way out of a flight must keep R as the plan does. `plan_landing` takes every vehicle's
current position, velocity and acceleration (world frame ENU, e.g. the flying plan's state at
a switch instant) and plans, with the same SCP planner, a move to a touchdown point at the
landing height (the workspace floor plus `landing_height`) below or beside each vehicle:

- touchdown points start straight below the vehicles and are pushed apart (in the
  separation metric, horizontally) until every two are at least R (1 + `TOUCHDOWN_SLACK`)
  apart, inside the workspace: vehicles stacked above each other land side by side;
- the horizon is what the farthest vehicle needs under the velocity and acceleration boxes
  (stopping from its current velocity, then its move), with room to give way;
- the result is verified like every plan (continuous-time separation, boxes, boundary
  conditions, flyability). The separation it keeps is R, or less where the fleet's state
  does not allow R: vehicles already closer than R cannot be planned apart in no time, and
  a pair passing each other near R keeps what the first step's rows allow
  (`first_step_clearance`, a few centimetres less); a vehicle that starts closer than R
  to a fixed one (a lost vehicle, predicted) keeps what it starts with from that one
  alone, growing back to R + its margin within seconds (`fixed_start_clearances`), while
  every other pair keeps R.

Where no landing plan keeps R + margin from a fixed vehicle (a neighbour caught under or
beside a lost vehicle's column), a plan of the same kind moves the vehicles first: each
horizontally, at its own height, to a point clear of every fixed vehicle's whole column and
R from the others (`escape_points`), verified like a landing; from there each can go straight
down, and the caller plans the landing again once they are there.

Numerics only: the ground station streams the plan and hands over to PX4's Land at the
touchdown points (`gcs.flight.safety.landing`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from planner.errors import PlannerError
from planner.model.fixed import FixedTrajectory
from planner.model.from_state import scenario_from_state
from planner.model.scenario import RANGES, Scenario, minimum_transfer_time
from planner.options import ScpOptions
from planner.planning import plan
from planner.result import Plan, PlanStatus
from planner.types import FloatArray, IntArray

__all__ = ["STAGES", "LandingError", "LandingPlan", "escape_points", "first_step_clearance",
           "fixed_start_clearances", "plan_landing", "touchdown_points"]


#: Touchdown points keep R (1 + this) apart horizontally, so that a vehicle descending
#: vertically onto its point (PX4 Land) stays R from one standing on its own.
TOUCHDOWN_SLACK = 0.05
#: Where the fleet's state holds R within this fraction of it (vehicles passing each other
#: near R), the landing keeps R (or less, `first_step_clearance`) minus this fraction: rows
#: linearised at the very edge of what the state allows leave its QP no room.
START_SLACK = 0.01
#: Rounds of pushing touchdown points apart before giving up (the floor is too crowded).
SPREAD_ROUNDS = 200
#: A fixed vehicle's column is the points it passes rounded to this grid (m): close enough
#: for the slack of `escape_points`, few enough to compare with every vehicle.
COLUMN_GRID = 0.05
#: The horizon is this many times the farthest vehicle's minimum time, plus `HORIZON_EXTRA_S`:
#: room for vehicles to give way to each other.
HORIZON_FACTOR = 1.5
HORIZON_EXTRA_S = 1.0
#: Speed (m/s) a landing is timed with where the scenario bounds no velocity.
DEFAULT_SPEED = 1.0
#: Horizons tried, as multiples of the first, when a plan fails to converge or verify. Not
#: when its first QP has no solution: the rows that break it are those the state fixes near
#: the start (a neighbour too close to open a fixed vehicle's margin in time), which a longer
#: horizon keeps, and proving a QP of 1.8 times the steps infeasible took up to 26 s of CPU
#: (paper-circle8, uav2 lost at 7.5 s) where the next share of the margin plans in 0.04 s.
RETRY_FACTORS = (1.0, 1.8)
#: SCP iterations allowed per attempt (a landing must be quick; unconverged is retried).
MAX_ITERATIONS = 12
#: What `plan_landing` tries, in turn: a landing, then (with vehicles it cannot steer) a
#: move away from their columns.
STAGES = ("landing", "escape")


class LandingError(PlannerError):
    """No verified landing plan: the reason in words (the caller falls back to PX4 Land)."""


@dataclass(frozen=True)
class LandingPlan:
    """A verified landing plan (or a move away first) and how it was made."""

    plan: Plan
    """Converged and verified; its goals are the touchdown points, its starts the state."""
    separation: float
    """The separation it keeps (m): R, or less where the state does not allow R
    (`first_step_clearance`); its verification checks the plan against this."""
    seconds: float
    """Planning time, touchdown placement included (s)."""
    attempts: int
    """Horizons tried (1 unless the first one failed)."""
    touchdown: bool = True
    """True: its goals are the touchdown points. False: no landing kept clear of the
    vehicles it cannot steer, and this plan moves the vehicles away from their columns
    (`escape_points`), from where a landing is planned again."""


def touchdown_points(positions: ArrayLike, scenario: Scenario, height: float,
                     fixed: Sequence[FixedTrajectory] = ()) -> FloatArray:
    """(N, 3) touchdown points at `height` (world z), each as near below its vehicle as the
    others and the obstacles allow: pushed apart until every two are R (1 + TOUCHDOWN_SLACK)
    apart in the horizontal separation metric, away from where each `fixed` vehicle comes
    to rest until they are R + its margin (1 + TOUCHDOWN_SLACK) from it horizontally, and
    out of every obstacle standing at that height until each is the obstacle clearance
    (1 + TOUCHDOWN_SLACK) from its footprint (the column below it is free: PX4's Land
    descends there), inside the workspace. `LandingError` when the floor is too crowded
    for that."""
    p = np.asarray(positions, dtype=float)
    rests = np.array([f.positions[-1, :2] for f in fixed]).reshape(-1, 2)
    out = np.empty_like(p)
    out[:, :2] = _spread(p, scenario, height, rests,
                         np.array([scenario.min_separation + f.margin for f in fixed]))
    out[:, 2] = height
    return out


def escape_points(positions: ArrayLike, scenario: Scenario, height: float,
                  fixed: Sequence[FixedTrajectory]) -> FloatArray:
    """(N, 3) points at each vehicle's own height from which it can go straight down: as
    `touchdown_points`, but clear of every point each `fixed` vehicle passes (its whole
    column, not only where it rests) by R + its margin (1 + TOUCHDOWN_SLACK) horizontally,
    so a vehicle there keeps that from it whatever it does and whenever. `LandingError` when
    the workspace is too crowded for that."""
    p = np.asarray(positions, dtype=float)
    paths = [np.unique(np.round(f.positions[:, :2] / COLUMN_GRID), axis=0) * COLUMN_GRID
             for f in fixed]
    out = p.copy()
    out[:, :2] = _spread(p, scenario, height, np.concatenate(paths).reshape(-1, 2),
                         np.concatenate([np.full(len(c), scenario.min_separation + f.margin)
                                         for c, f in zip(paths, fixed, strict=True)]))
    return out


def _spread(p: FloatArray, scenario: Scenario, height: float, avoid: FloatArray,
            avoid_need: FloatArray) -> FloatArray:
    """(N, 2) horizontal positions (m) as near `p`'s as allowed: every two R (1 +
    TOUCHDOWN_SLACK) apart in the horizontal separation metric, each `avoid_need[m]` (1 +
    TOUCHDOWN_SLACK) from `avoid[m]` (M, 2), clear of the obstacles standing at `height`,
    inside the workspace (`touchdown_points`)."""
    lim = scenario.limits
    scale = scenario.separation_scale[:2]
    need = scenario.min_separation * (1.0 + TOUCHDOWN_SLACK)
    lo, hi = lim.position_min[:2] / scale, lim.position_max[:2] / scale
    xy = np.clip(p[:, :2] / scale, lo, hi)
    avoid = avoid / scale
    avoid_need = avoid_need * (1.0 + TOUCHDOWN_SLACK)
    standing = _standing_at(scenario, height)
    rng = np.random.default_rng(0)  # only breaks exact coincidences, reproducibly
    for _ in range(SPREAD_ROUNDS):
        pairs = cKDTree(xy).query_pairs(need * (1.0 - 1e-9), output_type="ndarray")
        blocked = _obstacle_push(xy * scale, scenario, standing) / scale
        blocked += _away_from(xy, avoid, avoid_need, rng)
        if len(pairs) == 0 and not blocked.any():
            break
        moves = blocked
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            d = xy[j] - xy[i]
            dist = np.linalg.norm(d, axis=1)
            same = dist < 1e-9
            if same.any():
                angle = rng.uniform(0.0, 2.0 * math.pi, int(same.sum()))
                d[same] = np.stack([np.cos(angle), np.sin(angle)], axis=1)
                dist[same] = 1.0
            # each of the two moves half the shortfall (a little more, so the rounds end)
            push = (0.5 * (need - dist) * 1.01 + 1e-6)[:, None] * d / dist[:, None]
            np.add.at(moves, i, -push)
            np.add.at(moves, j, push)
        xy = np.clip(xy + moves, lo, hi)
    else:
        raise LandingError(f"cannot place {len(p)} points {need:.2f} m apart and clear of "
                           f"the obstacles and the vehicles it cannot steer within "
                           f"{SPREAD_ROUNDS} rounds (too crowded)")
    return xy * scale


def _away_from(xy: FloatArray, points: FloatArray, need: FloatArray,
               rng: np.random.Generator) -> FloatArray:
    """(N, 2) moves taking each of `xy` at least `need[m]` from each of `points` (M, 2),
    which do not move: by the sum of the shortfalls (a little more, so the rounds end)."""
    moves = np.zeros_like(xy)
    if len(points) == 0:
        return moves
    d = xy[:, None, :] - points[None, :, :]  # (N, M, 2)
    dist = np.linalg.norm(d, axis=2)
    short = dist < need[None, :] * (1.0 - 1e-9)
    if not short.any():
        return moves
    same = short & (dist < 1e-9)
    if same.any():
        angle = rng.uniform(0.0, 2.0 * math.pi, int(same.sum()))
        d[same] = np.stack([np.cos(angle), np.sin(angle)], axis=1)
        dist[same] = 1.0
    n, m = np.nonzero(short)
    push = ((need[m] - dist[n, m]) * 1.01 + 1e-6)[:, None] * d[n, m] / dist[n, m, None]
    np.add.at(moves, n, push)
    return moves


def _stopping(v: FloatArray, scenario: Scenario) -> FloatArray:
    """(N, 3) horizontal displacement of each vehicle braking at the acceleration bound
    from velocity `v` (zero without one): where it comes to a stop if it brakes now, so its
    touchdown point lies ahead of it rather than behind (no turning back)."""
    out = np.zeros_like(v)
    a_max = scenario.limits.acceleration_max
    if a_max is not None:
        out[:, :2] = v[:, :2] * np.abs(v[:, :2]) / (2.0 * a_max[:2])
    return out


def _standing_at(scenario: Scenario, height: float) -> IntArray:
    """Indices of the obstacles whose solid comes within the clearance of `height`: a
    touchdown point (and the descent below it) must stay clear of their footprints."""
    if not scenario.obstacles:
        return np.zeros(0, dtype=np.intp)
    z = scenario.obstacle_set.z
    reach = scenario.clearance
    return np.flatnonzero((z[:, 0] - reach <= height) & (height <= z[:, 1] + reach))


def _obstacle_push(xy: FloatArray, scenario: Scenario, standing: IntArray) -> FloatArray:
    """(N, 2) horizontal moves (m) that take each point out of the clearance of the
    obstacles in `standing` (zero for points already clear): along the footprint's outward
    normal, by the shortfall (a little more, so the rounds end)."""
    moves = np.zeros_like(xy)
    if len(standing) == 0 or len(xy) == 0:
        return moves
    geometry = scenario.obstacle_set
    need = scenario.clearance * (1.0 + TOUCHDOWN_SLACK)
    point = np.repeat(np.arange(len(xy)), len(standing))
    obstacle = np.tile(standing, len(xy))
    dh, _, normal = geometry.horizontal(xy[point], obstacle)
    short = dh < need * (1.0 - 1e-9)
    if short.any():
        push = ((need - dh[short]) * 1.01 + 1e-6)[:, None] * normal[short]
        np.add.at(moves, point[short], push)
    return moves


def first_step_clearance(p: FloatArray, v: FloatArray, a: FloatArray, scenario: Scenario
                         ) -> float:
    """The separation a plan starting in this state can be held to (m, scaled metric): the
    first step's rows are nearly fixed by the state (p0 and v0 are, a0 stays within the jerk
    box of the acceleration before), so they hold for at most the smallest value, along the
    direction of the closest point of the step's chord (the SCP's direction for a moving
    start, `planner.scp.separation.directions`), of the step's start, middle point and end with
    a0 unchanged. From a verified plan's state this is R within a fraction of a millimetre.
    inf when no two vehicles come within R (1 + START_SLACK) over the step."""
    if len(p) < 2:
        return math.inf
    scale = scenario.separation_scale
    dt = scenario.dt
    scaled = p / scale
    # pairs that can come within R over the step (each moves at most |v| dt + |a| dt^2 / 2)
    reach = float(np.max(np.linalg.norm((v * dt + 0.5 * dt * dt * np.abs(a)) / scale,
                                        axis=1)))
    near = scenario.min_separation * (1.0 + START_SLACK) + 2.0 * reach + 1e-9
    pairs = cKDTree(scaled).query_pairs(near, output_type="ndarray")
    if len(pairs) == 0:
        return math.inf
    i, j = pairs[:, 0], pairs[:, 1]
    d0 = scaled[i] - scaled[j]
    dv = (v[i] - v[j]) / scale
    da = (a[i] - a[j]) / scale
    return float(np.min(_chord_floor(d0, d0 + 0.5 * dt * dv,
                                     d0 + dt * dv + 0.5 * dt * dt * da))) * (1.0 - 1e-9)


def _chord_floor(d0: FloatArray, middle: FloatArray, d1: FloatArray) -> FloatArray:
    """(pairs,) the smallest of the three control points (pairs, 3 each, scaled) of a
    step's relative motion along the direction of the chord's closest point to the origin:
    what the step's three rows can hold the pair to."""
    chord = d1 - d0
    along = np.clip(-np.einsum("rc,rc->r", d0, chord)
                    / np.maximum(np.einsum("rc,rc->r", chord, chord), 1e-18), 0.0, 1.0)
    closest = d0 + along[:, None] * chord
    u = closest / np.maximum(np.linalg.norm(closest, axis=1), 1e-12)[:, None]
    nearest: FloatArray = np.minimum.reduce([np.einsum("rc,rc->r", u, x)
                                             for x in (d0, middle, d1)])
    return nearest


def fixed_start_clearances(p: FloatArray, v: FloatArray, a: FloatArray, ids: Sequence[str],
                           fixed: Sequence[FixedTrajectory], scenario: Scenario
                           ) -> list[FixedTrajectory]:
    """`fixed` with each pair that cannot keep R from the state named in its
    `start_clearance`: the first step's rows hold the pair to at most `_chord_floor` of
    its relative motion, and a vehicle still closing in after it comes nearer by its
    braking distance at half the acceleration bound; a pair whose least of the two is under
    R (1 + START_SLACK) keeps that less START_SLACK R, and grows back to R + margin over
    `planner.model.fixed.CLEARANCE_RAMP_S`. Every other pair keeps R + margin."""
    if not fixed or len(p) == 0:
        return list(fixed)
    scale = scenario.separation_scale
    dt = scenario.dt
    r = scenario.min_separation
    brake = (None if scenario.limits.acceleration_max is None
             else 0.5 * float(np.min(scenario.limits.acceleration_max / scale)))
    out = []
    for f in fixed:
        q, w, _ = (x[:2] for x in f.motion(dt, max(2, len(f))))
        d0 = (p - q[0]) / scale
        middle = d0 + 0.5 * dt * (v - w[0]) / scale
        d1 = (p + dt * v + 0.5 * dt * dt * a - q[1]) / scale
        floor = _chord_floor(d0, middle, d1)
        if brake is not None:  # still closing in after the step: its braking distance
            gap = np.linalg.norm(d1, axis=1)
            closing = -np.einsum("nc,nc->n", d1, (v + dt * a - w[1]) / scale) \
                / np.maximum(gap, 1e-12)
            floor = np.minimum(floor, gap - np.maximum(closing, 0.0) ** 2 / (2.0 * brake))
        short = floor < r * (1.0 + START_SLACK)
        if not short.any():
            out.append(f)
            continue
        keep = np.minimum(r, floor * (1.0 - 1e-9)) - START_SLACK * r
        least = RANGES["min_separation"][0]
        if (keep[short] < least).any():
            n = int(np.flatnonzero(short)[np.argmin(keep[short])])
            raise LandingError(f"{ids[n]} is too close to {f.id} to plan around it: the "
                               f"first step keeps {max(float(floor[n]), 0.0):.3f} m, a plan "
                               f"needs at least {least:g} m")
        out.append(replace(f, start_clearance={
            **f.start_clearance, **{ids[int(n)]: float(keep[n]) for n in np.flatnonzero(short)}}))
    return out


def _horizon(starts: FloatArray, velocities: FloatArray, goals: FloatArray,
             scenario: Scenario) -> float:
    """Seconds the landing gets: the farthest vehicle's stop and move, with room to spare."""
    lim = scenario.limits
    move = minimum_transfer_time(goals - starts, lim.velocity_max, lim.acceleration_max)
    speed = (DEFAULT_SPEED if lim.velocity_max is None
             else min(DEFAULT_SPEED, float(lim.velocity_max.min())))
    nominal = np.linalg.norm(goals - starts, axis=1) / speed
    stop = (np.zeros(len(starts)) if lim.acceleration_max is None
            else np.max(np.abs(velocities) / lim.acceleration_max, axis=1))
    need = max(float(np.max(move.max(axis=1) + 2.0 * stop)), float(np.max(nominal)))
    return HORIZON_FACTOR * need + HORIZON_EXTRA_S


def plan_landing(scenario: Scenario, positions: ArrayLike, velocities: ArrayLike,
                 accelerations: ArrayLike, *, ids: list[str] | None = None,
                 landing_height: float = 0.0, solver: str | None = None,
                 deadline: float | None = None, fixed: Sequence[FixedTrajectory] = (),
                 stages: Sequence[str] = STAGES) -> LandingPlan:
    """A verified landing plan for vehicles at `positions` (N, 3) moving with `velocities`
    and `accelerations` (N, 3), under `scenario`'s workspace, boxes, R and step length,
    keeping R + margin from the vehicles it cannot steer (`fixed`, from the plan's start:
    a lost vehicle on its own failsafe), whose resting points the touchdown points keep
    clear of too; the plan lasts at least as long as the longest of them. Where no landing
    keeps clear of them, the plan moves the vehicles away from their columns first
    (`LandingPlan.touchdown` False, `escape_points`), and the caller plans the landing again
    from there. stages: which of "landing" and "escape" to try, in turn.

    ids: the vehicles' ids (default `scenario.ids`, which needs N equal to its size).
    landing_height: touchdown height above the workspace floor (m). deadline: a
    `time.perf_counter()` instant after which no further attempt starts. Raises
    `LandingError` when no verified plan was found, for whatever reason (vehicles too close
    to hold any separation, a state the scenario refuses, a solver failure).
    """
    began = time.perf_counter()
    p, v, a, names, height = _fleet_state(scenario, positions, velocities, accelerations, ids,
                                          landing_height)
    goals = touchdown_points(p + _stopping(v, scenario), scenario, height, fixed)
    fixed = fixed_start_clearances(p, v, a, names, fixed, scenario)
    clearance = first_step_clearance(p, v, a, scenario)
    separation = scenario.min_separation
    if clearance < separation + START_SLACK * separation:
        # rows at the very edge of what the state allows leave the QP no room: give a hair
        separation = min(separation, clearance) - START_SLACK * separation
    least = RANGES["min_separation"][0]
    if not separation >= least:  # vehicles (nearly) touching: no scenario can hold them
        raise LandingError(f"two vehicles are too close to plan a landing: the first step "
                           f"keeps {max(clearance, 0.0):.3f} m, a plan needs at least "
                           f"{least:g} m")
    longest = max(((len(f) - 1) * scenario.dt for f in fixed), default=0.0)

    def attempts(label: str, to: FloatArray, horizon: float) -> LandingPlan:
        """The first verified plan to `to` over `horizon` times each of `RETRY_FACTORS`."""
        failures: list[str] = []
        for attempt, factor in enumerate(RETRY_FACTORS, start=1):
            if deadline is not None and attempt > 1 and time.perf_counter() > deadline:
                break
            steps = max(3, math.ceil(factor * horizon / scenario.dt))
            try:
                spec = scenario_from_state(scenario, label, names, p, v, a, to,
                                           separation=separation, steps=steps,
                                           max_iterations=MAX_ITERATIONS,
                                           fixed=[_truncated(f, steps) for f in fixed])
                result = plan(spec, solver=solver, options=ScpOptions(), method="whole")
            except (PlannerError, ValueError, ArithmeticError) as exc:  # the caller falls back
                raise LandingError(f"cannot plan the {label}: {exc}") from exc
            if result.ok:
                return LandingPlan(result, separation, time.perf_counter() - began, attempt,
                                   touchdown=label == "landing")
            failures.append(f"{steps * scenario.dt:.1f} s: {'; '.join(result.problems())}")
            if result.status == PlanStatus.INFEASIBLE and len(result.iterations) <= 1:
                break  # its first QP has no solution: a longer one, far slower, neither
        raise LandingError(f"no verified {label} plan (" + " | ".join(failures) + ")")

    failed: list[str] = []
    for stage in stages:
        if stage == "escape" and not fixed:
            continue  # nothing to move away from
        if failed and deadline is not None and time.perf_counter() > deadline:
            break
        try:
            if stage == "landing":
                return attempts(stage, goals, max(_horizon(p, v, goals, scenario), longest))
            # no landing keeps clear of them: move away from their columns first, land later
            away = escape_points(p + _stopping(v, scenario), scenario, height, fixed)
            return attempts(stage, away, _horizon(p, v, away, scenario))
        except LandingError as exc:
            failed.append(str(exc))
    raise LandingError("; ".join(failed) or f"no stage to try among {list(stages)}")


def _fleet_state(scenario: Scenario, positions: ArrayLike, velocities: ArrayLike,
                 accelerations: ArrayLike, ids: list[str] | None, landing_height: float
                 ) -> tuple[FloatArray, FloatArray, FloatArray, list[str], float]:
    """(p, v, a, ids, touchdown height) of the fleet a landing is planned from, checked
    (`LandingError`) and brought inside the scenario's boxes."""
    lim = scenario.limits
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    v = np.asarray(velocities, dtype=float).reshape(-1, 3)
    a = np.asarray(accelerations, dtype=float).reshape(-1, 3)
    names = scenario.ids if ids is None else list(ids)
    if not len(p) == len(v) == len(a) == len(names) or len(p) == 0:
        raise LandingError("positions, velocities, accelerations and ids must agree in length")
    if not (np.isfinite(p).all() and np.isfinite(v).all() and np.isfinite(a).all()):
        raise LandingError("the fleet's state is not finite")
    floor, ceiling = float(lim.position_min[2]), float(lim.position_max[2])
    height = floor + landing_height
    if not floor <= height <= ceiling:
        raise LandingError(f"landing height {landing_height:g} m lies outside the workspace")
    # A measured state may lie a hair outside the boxes; plan from the nearest state inside.
    p = np.clip(p, lim.position_min, lim.position_max)
    if lim.velocity_max is not None:
        v = np.clip(v, -lim.velocity_max, lim.velocity_max)
    if lim.acceleration_max is not None:
        a = np.clip(a, -lim.acceleration_max, lim.acceleration_max)
    return p, v, a, names, height


def _truncated(f: FixedTrajectory, steps: int) -> FixedTrajectory:
    """`f` over a plan of `steps` steps (a plan shorter than its motion, which
    `escape_points` keeps clear of all the same)."""
    if len(f) <= steps + 1:
        return f
    return replace(f, positions=f.positions[:steps + 1],
                   velocities=None if f.velocities is None else f.velocities[:steps + 1])
