"""Verification of trajectories, independent of the solver and of the QP's rows.

Everything is measured on the trajectories themselves with their exact motion between
steps: pair distances at the steps and over continuous time, every box (position checked
over continuous time too, since it is quadratic inside a step), boundary conditions, and
the flyability of thrust and body rates.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from planner.model.flatness import body_rates, jerk_from_accelerations, thrust
from planner.model.scenario import Scenario
from planner.result import Plan, Verification
from planner.scp.separation import (
    NEAR_MIN_VEHICLES,
    interval_lower_bounds,
    interval_minima,
    min_step_distance,
    near_pairs,
)
from planner.types import FloatArray
from planner.verification.clearance import closest_obstacle
from planner.verification.fixed_clearance import closest_fixed
from planner.verification.ground import airborne_spans, starts_on_the_ground

__all__ = ["BOUND_TOLERANCE", "SEPARATION_TOLERANCE", "refusal", "verify"]


#: A plan is separated when its continuous-time minimum is at least R minus this (m).
SEPARATION_TOLERANCE = 1e-4
#: Boxes and boundary conditions must hold within this.
BOUND_TOLERANCE = 1e-5


def _excess(values: FloatArray, bound: FloatArray | None) -> float:
    if bound is None or values.size == 0:
        return 0.0
    return float(max(0.0, np.max(np.abs(values) - bound)))


def _position_extremes(p: FloatArray, v: FloatArray, a: FloatArray, dt: float
                       ) -> tuple[FloatArray, FloatArray]:
    """Per vehicle and axis, min and max position over continuous time."""
    p0, v0, a0 = p[:, :-1], v[:, :-1], a
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(np.abs(a0) > 1e-12, -v0 / a0, 0.0)
    s = np.clip(s, 0.0, dt)
    inner = p0 + s * v0 + 0.5 * s * s * a0
    lo = np.minimum(p.min(axis=1), inner.min(axis=1))
    hi = np.maximum(p.max(axis=1), inner.max(axis=1))
    return lo, hi


def continuous_minimum(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray
                       ) -> tuple[float, float, int, int, float]:
    """(step minimum, continuous minimum, i, j, time) of the scaled pair distance."""
    scale = scenario.separation_scale
    pairs = None
    if len(p) >= NEAR_MIN_VEHICLES:
        # Broad phase: pairs left out stay farther than `reach` at every instant; if some
        # pair comes closer, the minimum is among the near ones. A fleet that keeps every
        # pair farther (widely spaced formations) widens the reach until one comes closer,
        # never falling back to all pairs over the whole timeline unless the reach spans the
        # fleet.
        reach = 2.0 * scenario.min_separation
        while True:
            pairs = near_pairs(p, v, a, scenario.dt, scale, reach)
            found = min_step_distance(p, scale, pairs)
            if found[0] < reach:
                break
            reach *= 2.0
    else:
        found = min_step_distance(p, scale, pairs)
    step_min, i, j, k = found
    if i < 0:
        return float("inf"), float("inf"), -1, -1, 0.0
    best = (step_min, i, j, k * scenario.dt)
    # The step minimum bounds the continuous one from above: only intervals whose cheap
    # lower bound goes under it can hold something smaller.
    maybe = interval_lower_bounds(p, a, scenario.dt, scale, step_min, pairs)
    if len(maybe):
        minima, when = interval_minima(p, v, a, scenario.dt, scale, maybe)
        idx = int(np.argmin(minima))
        if minima[idx] < best[0]:
            best = (float(minima[idx]), int(maybe.i[idx]), int(maybe.j[idx]),
                    float(maybe.k[idx] * scenario.dt + when[idx]))
    return step_min, best[0], best[1], best[2], best[3]


def airborne_minimum(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray
                     ) -> tuple[float, float, int, int, float]:
    """`continuous_minimum` over the pairs in the air only (`planner.verification.ground`):
    each run of steps with the same drones in the air is measured on its own."""
    step_best = float("inf")
    best = (float("inf"), -1, -1, 0.0)
    for first, end, drones in airborne_spans(p, v, a):
        found = continuous_minimum(scenario, p[drones, first:end + 1],
                                   v[drones, first:end + 1], a[drones, first:end])
        if found[2] < 0:
            continue
        step_best = min(step_best, found[0])
        if found[1] < best[0]:
            best = (found[1], int(drones[found[2]]), int(drones[found[3]]),
                    found[4] + first * scenario.dt)
    return (step_best, *best)


def _finite(x: float) -> float | None:
    """`x`, or None where it is NaN or infinite (undefined: JSON has neither)."""
    return float(x) if np.isfinite(x) else None


def _worst(values: dict[str, float]) -> dict[str, float | None]:
    return {key: _finite(x) for key, x in values.items()}


def verify(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray, *,
           ground: bool = False) -> Verification:
    """Check trajectories (N, K+1, 3) / (N, K, 3) against every requirement of the scenario.
    With `ground` (a show that takes off from and lands on the ground), separation counts
    only between drones both in the air (`airborne_minimum`).

    A figure that cannot be computed (non-finite motion, or a distance that overflows the
    separation metric) is reported as None and fails its check: undefined is never a pass.
    """
    lim = scenario.limits
    dt = scenario.dt
    finite = bool(np.isfinite(p).all() and np.isfinite(v).all() and np.isfinite(a).all())
    pairs = len(p) >= 2
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        measurable = finite and bool(np.isfinite(p / scenario.separation_scale).all())
        if measurable:
            step_min, cont_min, i, j, when = (airborne_minimum if ground
                                              else continuous_minimum)(scenario, p, v, a)
        else:
            step_min, cont_min, i, j, when = math.nan, math.nan, -1, -1, 0.0
        lo, hi = _position_extremes(p, v, a, dt)
        jerk = jerk_from_accelerations(a, dt, scenario.start_accelerations)
        f = thrust(a)
        rates = body_rates(a, jerk)
        violation = {
            "position": float(max(0.0, np.max(lim.position_min - lo),
                                  np.max(hi - lim.position_max))),
            "velocity": _excess(v, lim.velocity_max),
            "acceleration": _excess(a, lim.acceleration_max),
            "jerk": _excess(jerk, lim.jerk_max),
        }
        boundary = _boundary_errors(scenario, p, v, a)
        thrust_range = [float(f.min()), float(f.max())]
        rate_peak = float(np.max(np.abs(rates[..., :2])))
    # With two or more vehicles the minimum must be a number: inf or NaN means the metric
    # overflowed or the motion is undefined, not that the vehicles are far apart.
    measured = not pairs or (math.isfinite(step_min) and math.isfinite(cont_min) and i >= 0)
    flyable = (
        finite
        and bool(np.isfinite(f).all() and np.isfinite(rates).all())
        and thrust_range[0] >= lim.thrust_min
        and thrust_range[1] <= lim.thrust_max
        and rate_peak <= lim.body_rate_max
    )
    # NaN compares false everywhere (and max(0.0, nan) is 0.0): finiteness is checked first
    bounded = finite and all(math.isfinite(x) for x in (*violation.values(),
                                                        *boundary.values()))
    ids = scenario.ids
    obstacle = _obstacle_figures(scenario, p, v, a, finite)
    fixed, fixed_ok = _fixed_figures(scenario, p, v, a, measurable)
    return Verification(
        min_separation=step_min if pairs and measured else None,
        min_separation_continuous=cont_min if pairs and measured else None,
        closest_pair=[ids[i], ids[j]] if pairs and measured else [],
        closest_time=float(when) if pairs and measured else 0.0,
        max_violation=_worst(violation),
        boundary_error=_worst(boundary),
        thrust_range=[_finite(x) for x in thrust_range],
        body_rate_peak=_finite(rate_peak),
        flyable=bool(flyable),
        separated=bool(fixed_ok and (not pairs or (measured
                                                   and cont_min >= scenario.min_separation
                                                   - SEPARATION_TOLERANCE))),
        within_bounds=bool(
            bounded
            and max(violation.values()) <= BOUND_TOLERANCE
            and max(boundary.values()) <= BOUND_TOLERANCE
        ),
        separation_tolerance=SEPARATION_TOLERANCE,
        bound_tolerance=BOUND_TOLERANCE,
        **obstacle,
        **fixed,
    )


def _boundary_errors(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray
                     ) -> dict[str, float]:
    """The largest miss of each boundary condition: the start's state, and rest at the goal."""
    return {
        "start_position": float(np.max(np.abs(p[:, 0] - scenario.starts))),
        "start_velocity": float(np.max(np.abs(v[:, 0] - scenario.initial_velocities))),
        # each vehicle's own goal: the assigned one under free assignment
        "goal_position": float(np.max(np.abs(p[:, -1] - scenario.assigned_goals))),
        "goal_velocity": float(np.max(np.abs(v[:, -1]))),
        "goal_acceleration": float(np.max(np.abs(a[:, -1]))),
    }


def _obstacle_figures(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray,
                      finite: bool) -> dict[str, Any]:
    """The closest any vehicle comes to an obstacle and whether that keeps the clearance: {}
    without obstacles, None figures and not clear when it cannot be measured."""
    if not scenario.obstacles:
        return {}
    near = closest_obstacle(scenario, p, v, a) if finite else None
    if near is None or not math.isfinite(near.distance):
        return {"obstacle_distance_min": None, "clear": False, "closest_obstacle": None}
    return {
        "obstacle_distance_min": near.distance,
        "closest_obstacle": {"id": scenario.obstacles[near.obstacle].id,
                             "vehicle": scenario.ids[near.vehicle], "time": near.time},
        "clear": near.distance >= scenario.clearance - SEPARATION_TOLERANCE,
    }


def _fixed_figures(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray,
                   measurable: bool) -> tuple[dict[str, Any], bool]:
    """The closest any vehicle comes to a fixed trajectory and whether that keeps what the
    pair needs: ({}, True) without fixed trajectories, None figures and False when it cannot
    be measured."""
    if not scenario.fixed:
        return {}, True
    nearest = closest_fixed(scenario, p, v, a) if measurable else None
    if nearest is None or not math.isfinite(nearest.distance):
        return {"fixed_distance_min": None, "closest_fixed": {}}, False
    return {
        "fixed_distance_min": nearest.distance,
        "closest_fixed": {"id": scenario.fixed[nearest.fixed].id,
                          "vehicle": scenario.ids[nearest.vehicle], "time": nearest.time,
                          "required": nearest.required},
    }, nearest.distance >= nearest.required - SEPARATION_TOLERANCE


def refusal(plan: Plan) -> str | None:
    """Why `plan` must not be flown or handed to a show tool, checked anew on its
    trajectories (a plan file's own verification block is only a claim: it may have been
    edited, or written by another tool); None when it converged and verifies."""
    if plan.status != "converged":
        return f"its status is {plan.status!r}" + (f": {plan.message}" if plan.message else "")
    check = verify(plan.scenario, plan.positions(), plan.velocities(), plan.accelerations(),
                   ground=starts_on_the_ground(plan.sequence))
    if not check.verified:
        return "it fails verification: " + "; ".join(check.failures())
    for key, moving in (("start_velocity", plan.scenario.start_velocities),
                        ("start_acceleration", plan.scenario.start_accelerations)):
        if moving is not None and np.any(moving != 0.0):
            n = int(np.flatnonzero(np.any(moving != 0.0, axis=1))[0])
            return (f"it starts moving (vehicles[{n}].{key}): a flight or show starts "
                    f"from a hover at the starts")
    return None
