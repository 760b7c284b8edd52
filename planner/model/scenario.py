"""The scenario model (the input JSON contract) and its validation.

Long: the scenario contract: its dataclasses and the parser that names every field.

A scenario is parsed once into frozen dataclasses holding numpy arrays; every problem found is
a `ScenarioError` naming the field (dotted path) and the reason. `Scenario.to_dict` echoes the
scenario with every default filled in, which is what a plan carries.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from planner.errors import FieldError, ScenarioError, ScenarioErrors
from planner.methods.assignment import assign_goals
from planner.model.checks import (
    RANGES,
    check_id,
    check_keys,
    check_list,
    check_number,
    check_vector,
)
from planner.model.checks import check_integer as _integer
from planner.model.choices import ASSIGNMENTS, Assignment
from planner.types import FloatArray, IntArray

if TYPE_CHECKING:
    from planner.model.fixed import FixedSet, FixedTrajectory
    from planner.model.obstacle_set import ObstacleSet
    from planner.model.obstacles import Obstacle

__all__ = ["ASSIGNMENTS", "AUTO_STEPS", "DEFAULTS", "DEFAULT_MAX_HORIZON", "METHODS", "RANGES",
           "Assignment", "Limits", "Scenario", "Vehicle", "check_id", "check_keys", "check_number",
           "check_vector", "minimum_transfer_time"]


#: Defaults filled in when a scenario omits a key (documented in the README).
DEFAULTS: dict[str, Any] = {
    "name": "scenario",
    "cost_threshold": 0.05,
    "max_iterations": 30,
    "separation_scale": [1.0, 1.0, 1.0],
    "thrust_min": 2.0,
    "thrust_max": 18.0,
    "body_rate_max": 6.0,
    "assignment": "fixed",
    "method": "auto",
}

#: `method` values, how the fleet is planned (`planner.methods.stages`): "auto" (both methods at
# once
#: where both apply, the first verified plan wins), "whole" (the whole fleet's SCP) or
#: "prioritized" (batches, each around the earlier ones; the whole fleet if they fail).
METHODS = ("auto", "whole", "prioritized")

#: Hard caps that keep one scenario from exhausting memory (not physical limits). A record
#: drone show is about 16,000 vehicles; a service sets its own, lower fleet limit
#: (`max_vehicles`, `gcs.service.limits`).
MAX_VEHICLES = 20_000
MAX_STEPS = 5000
MAX_ITERATIONS = 1000

#: `steps` value that asks the planner to choose the horizon (`planner.methods.horizon_search`).
AUTO_STEPS = "auto"
#: Longest horizon (s) a `steps: "auto"` search tries when the scenario gives no
#: `max_horizon`; the search never goes past `MAX_STEPS` steps either.
DEFAULT_MAX_HORIZON = 300.0

#: A setting's checked value (`_settings`).
_T = TypeVar("_T")

#: Largest `max_horizon` a scenario may give (s): a sanity bound, an hour of flight.
MAX_HORIZON_LIMIT = 3600.0


_TOP_KEYS = {
    "name", "dt", "steps", "min_separation", "separation_scale", "cost_threshold",
    "max_iterations", "limits", "vehicles", "assignment", "separation_margin",
    "obstacles", "obstacle_clearance", "fixed", "max_horizon", "method",
}
_LIMIT_KEYS = {
    "position_min", "position_max", "velocity_max", "acceleration_max", "jerk_max",
    "thrust_min", "thrust_max", "body_rate_max",
}
_VEHICLE_KEYS = {"id", "start", "goal", "start_velocity", "start_acceleration"}


@dataclass(frozen=True)
class Limits:
    """Workspace box and per-axis motion bounds (symmetric), plus flyability limits."""

    position_min: FloatArray
    """Lower corner of the workspace box (m)."""
    position_max: FloatArray
    """Upper corner of the workspace box (m)."""
    velocity_max: FloatArray | None
    """Per-axis |v| bound (m/s), or None for unbounded."""
    acceleration_max: FloatArray | None
    """Per-axis |a| bound (m/s^2), or None for unbounded."""
    jerk_max: FloatArray | None
    """Per-axis |j| bound (m/s^3), or None for unbounded."""
    thrust_min: float
    """Lowest allowed mass-normalised thrust ||a + g|| (m/s^2), for the flyability check."""
    thrust_max: float
    """Highest allowed mass-normalised thrust (m/s^2), for the flyability check."""
    body_rate_max: float
    """Highest allowed roll/pitch body rate (rad/s), for the flyability check."""

    def to_dict(self) -> dict[str, Any]:
        def opt(a: FloatArray | None) -> list[float] | None:
            return None if a is None else a.tolist()

        out: dict[str, Any] = {
            "position_min": self.position_min.tolist(),
            "position_max": self.position_max.tolist(),
            "velocity_max": opt(self.velocity_max),
            "acceleration_max": opt(self.acceleration_max),
            "jerk_max": opt(self.jerk_max),
            "thrust_min": self.thrust_min,
            "thrust_max": self.thrust_max,
            "body_rate_max": self.body_rate_max,
        }
        return {k: v for k, v in out.items() if v is not None}


@dataclass(frozen=True)
class Vehicle:
    """One vehicle's task: fly from `start` (at rest, unless `start_velocity` says it is
    moving) to `goal` (at rest), world frame ENU."""

    id: str
    """Unique vehicle id; a fleet file maps it to a vehicle."""
    start: FloatArray
    """Where the vehicle starts, hovering (m)."""
    goal: FloatArray
    """Where it must arrive and stop (m)."""
    start_velocity: FloatArray | None = None
    """Its velocity at the start (m/s); None: at rest (the JSON omits it)."""
    start_acceleration: FloatArray | None = None
    """Its acceleration just before the start (m/s^2), which the first step's jerk is
    measured from; None: hovering (the JSON omits it)."""


@dataclass(frozen=True)
class Scenario:
    """A validated planning problem. Build it with `Scenario.from_dict`."""

    name: str
    """Free-form name, shown in listings."""
    dt: float
    """Step length (s)."""
    steps: int
    """Number of steps K; the horizon is K * dt. The JSON may say "auto": the planner
    chooses the shortest horizon with a verified plan (`planner.methods.horizon_search`); parsed,
    K is then the fewest steps the velocity and acceleration boxes allow (`steps_auto`)."""
    min_separation: float
    """R (m): ||diag(1/scale) (p_i - p_j)|| >= R for every pair at every instant."""
    separation_scale: FloatArray
    """Per-axis scale of the separation metric; [1, 1, 2] is the downwash ellipsoid."""
    cost_threshold: float
    """SCP stops when the cost changes by less than this between iterations."""
    max_iterations: int
    """Cap on SCP iterations (the separation-free first QP counts as iteration 0)."""
    limits: Limits
    """Workspace box, motion bounds and flyability limits."""
    vehicles: tuple[Vehicle, ...]
    """The fleet's tasks, at least one; ids are unique."""
    starts: FloatArray = field(repr=False)
    """(N, 3) start positions, in vehicle order."""
    goals: FloatArray = field(repr=False)
    """(N, 3) goal positions as given, in vehicle order."""
    assignment: str = "fixed"
    """'fixed': vehicle n flies to goals[n]; 'free': to goals[goal_order[n]]."""
    goal_order: IntArray | None = field(default=None, repr=False)
    """(N,) for 'free': the goal index each vehicle flies to (minimum total squared
    distance); None for 'fixed' (the identity)."""
    method: str = "auto"
    """How the fleet is planned: 'auto' (both methods at once where both apply, the first
    verified plan wins), 'whole' (the whole fleet's SCP) or 'prioritized' (batches, each
    around the earlier ones, and the whole fleet if they fail)."""
    separation_margin: float = 0.0
    """Part of `min_separation` (m) reserved for the fleet's position error in flight
    (2 x its expected error, `gcs.flight.safety.margin`): the vehicles must keep
    min_separation - separation_margin. The planner only carries it; 0 = none stated."""
    obstacles: tuple[Obstacle, ...] = ()
    """Keep-out volumes (boxes, vertical cylinders, convex prisms; `planner.model.obstacles`);
    ids are unique."""
    obstacle_clearance: float | None = None
    """Distance (m) every vehicle keeps from every obstacle's solid at every instant;
    default (None) min_separation / 2."""

    @property
    def clearance(self) -> float:
        """`obstacle_clearance` with its default resolved (m)."""
        if self.obstacle_clearance is None:
            return 0.5 * self.min_separation
        return self.obstacle_clearance

    @cached_property
    def obstacle_set(self) -> ObstacleSet:
        """The obstacles as arrays for vectorised geometry (built once)."""
        from planner.model.obstacle_set import ObstacleSet

        return ObstacleSet.build(self.obstacles)
    fixed: tuple[FixedTrajectory, ...] = ()
    """Vehicles whose motion is known and not planned (`planner.model.fixed`): the planned ones
    keep R + each one's margin from it at every instant (a pair named in its
    `start_clearance`: from what it starts with, growing back to that)."""

    @cached_property
    def fixed_set(self) -> FixedSet:
        """The fixed trajectories as arrays on the step grid (built once)."""
        from planner.model.fixed import FixedSet

        return FixedSet.build(self.fixed, self.dt, self.steps,
                              [v.id for v in self.vehicles], self.min_separation)

    def with_fixed_set(self, fixed_set: FixedSet) -> Scenario:
        """A copy whose `fixed_set` is `fixed_set` instead of one built from `fixed`: for a
        caller that has the arrays on this grid already (a prioritized batch's earlier
        vehicles, which are plans). `fixed_set` must describe `fixed` on this grid."""
        copy = dataclasses.replace(self)
        copy.__dict__["fixed_set"] = fixed_set  # the cached_property's own slot
        return copy
    start_velocities: FloatArray | None = field(default=None, repr=False)
    """(N, 3) start velocities (m/s), when some vehicle has one; None: all start at rest."""
    start_accelerations: FloatArray | None = field(default=None, repr=False)
    """(N, 3) accelerations before the start (m/s^2), when some vehicle has one; None: 0."""
    steps_auto: bool = field(default=False, repr=False)
    """`steps: "auto"`: `planner.plan` searches for the shortest horizon with a verified
    plan (`planner.methods.horizon_search`), up to `max_horizon`."""
    max_horizon: float | None = None
    """With steps "auto": the longest horizon the search tries (s; default 300, never more
    than 5000 steps); None (absent) with a fixed number of steps."""

    @property
    def max_steps(self) -> int:
        """With `steps_auto`: the most steps the search tries (`max_horizon` / dt, at most
        `MAX_STEPS`); otherwise `steps`."""
        if self.max_horizon is None:
            return self.steps
        return _steps_within(self.max_horizon, self.dt)

    def with_steps(self, steps: int) -> Scenario:
        """The same problem over a fixed number of steps (what a search candidate plans);
        the assignment is kept, not solved again."""
        return dataclasses.replace(self, steps=steps, steps_auto=False, max_horizon=None)

    @property
    def initial_velocities(self) -> FloatArray:
        """(N, 3) every vehicle's velocity at the start (zeros when all start at rest)."""
        if self.start_velocities is None:
            return np.zeros((len(self.vehicles), 3))
        return self.start_velocities

    @property
    def initial_accelerations(self) -> FloatArray:
        """(N, 3) every vehicle's acceleration before the start (the first jerk's a[-1])."""
        if self.start_accelerations is None:
            return np.zeros((len(self.vehicles), 3))
        return self.start_accelerations

    @property
    def order(self) -> IntArray:
        """(N,) the goal index each vehicle flies to (the identity for 'fixed')."""
        if self.goal_order is None:
            return np.arange(len(self.vehicles), dtype=np.intp)
        return self.goal_order

    @property
    def assigned_goals(self) -> FloatArray:
        """(N, 3) the goal each vehicle flies to, in vehicle order."""
        return self.goals[self.order]

    def assigned(self) -> Scenario:
        """The same problem with each vehicle's goal replaced by its assigned one and
        `assignment` fixed: what the SCP loop and the verifier work on."""
        if self.goal_order is None:
            return self
        goals = self.assigned_goals
        vehicles = tuple(dataclasses.replace(v, goal=g)
                         for v, g in zip(self.vehicles, goals, strict=True))
        return dataclasses.replace(self, vehicles=vehicles, goals=goals, assignment="fixed",
                                   goal_order=None)

    @property
    def horizon(self) -> float:
        return self.steps * self.dt

    @property
    def ids(self) -> list[str]:
        return [v.id for v in self.vehicles]

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, on_ground: bool = False) -> Scenario:
        """Parse and validate a scenario; raises `ScenarioError` naming the field. With
        `on_ground` (a show's whole timeline, which starts and ends on the ground), starts
        and goals on the ground (z <= 0) may stand closer than R: only those in the air are
        held to it (`planner.methods.ground`)."""
        return _parse(data, on_ground=on_ground)

    def to_dict(self) -> dict[str, Any]:
        """The scenario JSON with every default filled in."""
        return {
            "name": self.name,
            "dt": self.dt,
            "steps": AUTO_STEPS if self.steps_auto else self.steps,
            "min_separation": self.min_separation,
            "separation_scale": self.separation_scale.tolist(),
            "cost_threshold": self.cost_threshold,
            "max_iterations": self.max_iterations,
            "limits": self.limits.to_dict(),
            "assignment": self.assignment,
            "method": self.method,
            "vehicles": [_vehicle_dict(v) for v in self.vehicles],
        } | ({"separation_margin": self.separation_margin} if self.separation_margin else {}
             ) | ({"obstacle_clearance": self.clearance,
                   "obstacles": [o.to_dict() for o in self.obstacles]}
                  if self.obstacles or self.obstacle_clearance is not None else {}
             ) | ({"fixed": [f.to_dict() for f in self.fixed]} if self.fixed else {}
             ) | ({"max_horizon": self.max_horizon} if self.max_horizon is not None else {})


def _vehicle_dict(v: Vehicle) -> dict[str, Any]:
    """One vehicle's JSON; the start state only where it was given."""
    out: dict[str, Any] = {"id": v.id, "start": v.start.tolist(), "goal": v.goal.tolist()}
    if v.start_velocity is not None:
        out["start_velocity"] = v.start_velocity.tolist()
    if v.start_acceleration is not None:
        out["start_acceleration"] = v.start_acceleration.tolist()
    return out


# --------------------------------------------------------------------------- parsing helpers


def _parse_limits(data: Any) -> Limits:
    check_keys(data, _LIMIT_KEYS, "limits", ("position_min", "position_max"))
    pmin = check_vector(data["position_min"], "limits.position_min")
    pmax = check_vector(data["position_max"], "limits.position_max")
    for axis in range(3):
        if pmax[axis] <= pmin[axis]:
            raise ScenarioError(
                f"limits.position_max[{axis}]",
                f"must be greater than position_min[{axis}] ({pmin[axis]:g})",
            )

    def optional(key: str) -> FloatArray | None:
        value = data.get(key)
        return (None if value is None
                else check_vector(value, f"limits.{key}", positive=True, within=key))

    thrust_min = check_number(
        data.get("thrust_min", DEFAULTS["thrust_min"]), "limits.thrust_min", nonneg=True,
        within="thrust_min",
    )
    thrust_max = check_number(
        data.get("thrust_max", DEFAULTS["thrust_max"]), "limits.thrust_max", positive=True,
        within="thrust_max",
    )
    if thrust_max <= thrust_min:
        raise ScenarioError(
            "limits.thrust_max", f"must be greater than thrust_min ({thrust_min:g})"
        )
    body_rate_max = check_number(
        data.get("body_rate_max", DEFAULTS["body_rate_max"]), "limits.body_rate_max",
        positive=True, within="body_rate_max",
    )
    return Limits(
        position_min=pmin,
        position_max=pmax,
        velocity_max=optional("velocity_max"),
        acceleration_max=optional("acceleration_max"),
        jerk_max=optional("jerk_max"),
        thrust_min=thrust_min,
        thrust_max=thrust_max,
        body_rate_max=body_rate_max,
    )


def minimum_transfer_time(distance: FloatArray, v_max: FloatArray | None, a_max: FloatArray | None,
                          ) -> FloatArray:
    """Shortest rest-to-rest time to cover `distance` per axis under |v|, |a| bounds.

    A necessary condition only (jerk bounds and the discrete grid make the true time longer);
    used to reject horizons that cannot possibly work before any QP is solved.
    """
    d = np.abs(distance)
    if a_max is None:
        return np.zeros_like(d) if v_max is None else d / v_max
    bang_bang = 2.0 * np.sqrt(d / a_max)
    if v_max is None:
        return bang_bang
    cruise = d / v_max + v_max / a_max
    return np.where(d <= v_max * v_max / a_max, bang_bang, cruise)


def _closest_pair_within(points: FloatArray, scale: FloatArray, limit: float
                         ) -> tuple[float, int, int] | None:
    """The closest two points closer than `limit` in the separation metric, as (distance,
    i, j) with i < j (the first such pair in (i, j) order on ties), or None. A k-d tree finds
    the candidates: all pairs of 16,000 points would be 128 million distances."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(points / scale).query_pairs(limit, output_type="ndarray")
    if len(pairs) == 0:
        return None
    pairs = np.sort(pairs, axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    d = np.linalg.norm((points[pairs[:, 0]] - points[pairs[:, 1]]) / scale, axis=1)
    closer = d < limit
    if not closer.any():
        return None
    k = int(np.flatnonzero(closer)[np.argmin(d[closer])])
    return float(d[k]), int(pairs[k, 0]), int(pairs[k, 1])


@dataclass(frozen=True)
class _Settings:
    """A scenario's own settings, checked (everything but its vehicles and what they meet)."""

    name: str
    dt: float
    horizon: tuple[int, bool, float | None]
    """(steps, steps "auto", max_horizon): `_steps_setting`."""
    separation: tuple[float, float, FloatArray]
    """(min_separation, separation_margin, separation_scale): `_separation_setting`."""
    threshold: float
    max_iterations: int
    limits: Limits
    assignment: str
    method: str


def _settings(data: Mapping[str, Any]) -> _Settings:
    """The scenario's own settings, each checked alone, so that a document with several
    problems is told them all at once (`ScenarioErrors`; one alone is its `ScenarioError`)."""
    problems: list[FieldError] = []

    def checked(check: Callable[[], _T]) -> _T | None:
        try:
            return check()
        except ScenarioError as exc:
            problems.append(exc)
            return None

    name = checked(lambda: _name(data))
    dt = checked(lambda: check_number(data["dt"], "dt", positive=True, within="dt"))
    # the horizon's bounds are in steps of dt: judged only with a dt
    horizon = None if dt is None else checked(lambda: _steps_setting(data, dt))
    separation = checked(lambda: _separation_setting(data))
    threshold = checked(lambda: check_number(
        data.get("cost_threshold", DEFAULTS["cost_threshold"]), "cost_threshold",
        positive=True, within="cost_threshold"))
    max_iterations = checked(lambda: _integer(
        data.get("max_iterations", DEFAULTS["max_iterations"]), "max_iterations", 1,
        MAX_ITERATIONS))
    limits = checked(lambda: _parse_limits(data["limits"]))
    assignment = checked(lambda: _choice(data, "assignment", ASSIGNMENTS))
    method = checked(lambda: _choice(data, "method", METHODS))
    if problems:
        raise problems[0] if len(problems) == 1 else ScenarioErrors(problems)
    assert (name is not None and dt is not None and horizon is not None
            and separation is not None and threshold is not None
            and max_iterations is not None and limits is not None
            and assignment is not None and method is not None)
    return _Settings(name, dt, horizon, separation, threshold, max_iterations, limits,
                     assignment, method)


def _name(data: Mapping[str, Any]) -> str:
    name = data.get("name", DEFAULTS["name"])
    if not isinstance(name, str) or not name.strip():
        raise ScenarioError("name", "must be a non-empty string")
    return name


def _choice(data: Mapping[str, Any], key: str, choices: tuple[str, ...]) -> str:
    """`data[key]` (or its default), one of `choices`."""
    value = data.get(key, DEFAULTS[key])
    if not isinstance(value, str) or value not in choices:
        allowed = (" or ".join(map(repr, choices)) if len(choices) == 2
                   else f"one of {', '.join(map(repr, choices))}")
        raise ScenarioError(key, f"must be {allowed}, got {value!r}")
    return value


def _parse(data: Mapping[str, Any], *, on_ground: bool = False) -> Scenario:
    check_keys(data, _TOP_KEYS, "", ("dt", "steps", "min_separation", "limits", "vehicles"))
    settings = _settings(data)
    name, dt, limits = settings.name, settings.dt, settings.limits
    steps, steps_auto, max_horizon = settings.horizon
    separation, margin, scale = settings.separation
    threshold, max_iterations = settings.threshold, settings.max_iterations
    assignment, method = settings.assignment, settings.method

    vehicles = _parse_vehicles(data["vehicles"], limits)
    starts = np.array([v.start for v in vehicles])
    goals = np.array([v.goal for v in vehicles])
    start_velocities = _stack_given([v.start_velocity for v in vehicles])
    start_accelerations = _stack_given([v.start_acceleration for v in vehicles])
    _check_spacing(starts, goals, scale, separation, on_ground)

    from planner.model.obstacle_set import check_clear
    from planner.model.obstacles import parse_obstacles

    obstacles, clearance = parse_obstacles(data, separation)
    check_clear(obstacles, clearance, starts, "start")
    check_clear(obstacles, clearance, goals, "goal")

    from planner.model.fixed import check_fixed_clear, parse_fixed

    fixed = parse_fixed(data, [v.id for v in vehicles], steps)
    check_fixed_clear(fixed, separation, scale, starts, goals, [v.id for v in vehicles])

    goal_order = None
    if assignment == "free":
        goal_order = assign_goals(starts, goals, scale)
    steps = _reachable_steps(starts, goals if goal_order is None else goals[goal_order],
                             goal_order, start_velocities, limits, dt, steps, steps_auto,
                             max((len(f) - 1 for f in fixed), default=0))

    return Scenario(
        name=name,
        dt=dt,
        steps=steps,
        min_separation=separation,
        separation_scale=scale,
        cost_threshold=threshold,
        max_iterations=max_iterations,
        limits=limits,
        vehicles=tuple(vehicles),
        starts=starts,
        goals=goals,
        assignment=assignment,
        goal_order=goal_order,
        method=method,
        separation_margin=margin,
        start_velocities=start_velocities,
        start_accelerations=start_accelerations,
        obstacles=obstacles,
        obstacle_clearance=clearance if "obstacle_clearance" in data or obstacles else None,
        fixed=fixed,
        steps_auto=steps_auto,
        max_horizon=max_horizon,
    )


def _separation_setting(data: Mapping[str, Any]) -> tuple[float, float, FloatArray]:
    """(min_separation, separation_margin, separation_scale): the margin below R."""
    separation = check_number(data["min_separation"], "min_separation", positive=True,
                              within="min_separation")
    margin = check_number(data.get("separation_margin", 0.0), "separation_margin", nonneg=True,
                          within="separation_margin")
    if margin >= separation:
        raise ScenarioError("separation_margin", f"must be less than min_separation "
                                                 f"{separation:g} m, got {margin:g}")
    scale = check_vector(data.get("separation_scale", DEFAULTS["separation_scale"]),
                         "separation_scale", positive=True, within="separation_scale")
    return separation, margin, scale


def _parse_vehicles(data: Any, limits: Limits) -> list[Vehicle]:
    """The `vehicles` list: each one's keys, a unique id, a start and goal inside the
    workspace, and its optional start state."""
    raw_vehicles = check_list(data, "vehicles", "vehicles", MAX_VEHICLES)
    if not raw_vehicles:
        raise ScenarioError("vehicles", "must contain at least one vehicle")
    vehicles: list[Vehicle] = []
    seen: dict[str, int] = {}
    for index, raw in enumerate(raw_vehicles):
        where = f"vehicles[{index}]"
        check_keys(raw, _VEHICLE_KEYS, where, ("id", "start", "goal"))
        vid = check_id(raw["id"], f"{where}.id")
        if vid in seen:
            raise ScenarioError(f"{where}.id", f"duplicate id {vid!r} (also vehicles[{seen[vid]}])")
        seen[vid] = index
        start = check_vector(raw["start"], f"{where}.start")
        goal = check_vector(raw["goal"], f"{where}.goal")
        for label, point in (("start", start), ("goal", goal)):
            outside = (point < limits.position_min) | (point > limits.position_max)
            if outside.any():
                axis = int(np.argmax(outside))
                raise ScenarioError(
                    f"{where}.{label}",
                    f"{point.tolist()} lies outside the workspace on axis {'xyz'[axis]} "
                    f"[{limits.position_min[axis]:g}, {limits.position_max[axis]:g}]",
                )
        vehicles.append(Vehicle(vid, start, goal,
                                *_start_state(raw, where, limits)))
    return vehicles


def _check_spacing(starts: FloatArray, goals: FloatArray, scale: FloatArray,
                   separation: float, on_ground: bool) -> None:
    """No two starts, and no two goals, closer than min_separation (`on_ground`: only those
    in the air, z > 0, count)."""
    for label, points in (("start", starts), ("goal", goals)):
        held = np.flatnonzero(points[:, 2] > 0.0) if on_ground else np.arange(len(points))
        if len(held) < 2:
            continue
        closest = _closest_pair_within(points[held], scale, separation)
        if closest is not None:
            dist, i, j = closest[0], int(held[closest[1]]), int(held[closest[2]])
            raise ScenarioError(
                f"vehicles[{j}].{label}",
                f"is {dist:.3f} m from vehicles[{i}].{label} in the separation metric, "
                f"closer than min_separation {separation:g} m",
            )


def _reachable_steps(starts: FloatArray, targets: FloatArray, goal_order: IntArray | None,
                     start_velocities: FloatArray | None, limits: Limits, dt: float,
                     steps: int, steps_auto: bool, fixed_steps: int) -> int:
    """The scenario's steps once every vehicle can reach its goal (`targets`, in the
    vehicles' order) under the velocity and acceleration boxes: `steps` as given, or with
    `steps_auto` the fewest the boxes and the fixed trajectories' samples (`fixed_steps`)
    allow, the search's start. A goal out of reach names the vehicle and what it needs."""
    horizon = steps * dt
    # The last acceleration is pinned to zero, so the motion has (K-1) steps to happen in.
    usable = (steps - 1) * dt
    need = minimum_transfer_time(targets - starts, limits.velocity_max,
                                 limits.acceleration_max)
    if start_velocities is not None:
        # a rest-to-rest bound says nothing about a vehicle already moving: the QP judges it
        need[np.any(start_velocities != 0.0, axis=1)] = 0.0
    worst_vehicle, worst_axis = np.unravel_index(int(np.argmax(need)), need.shape)
    culprit = worst_vehicle if goal_order is None else int(goal_order[worst_vehicle])
    assigned = "" if goal_order is None else f" (assigned to vehicles[{worst_vehicle}])"
    distance = abs(targets[worst_vehicle, worst_axis] - starts[worst_vehicle, worst_axis])
    why = (f"moving {distance:.3f} m along {'xyz'[worst_axis]} needs at least "
           f"{need[worst_vehicle, worst_axis]:.2f} s under the velocity/acceleration limits")
    if steps_auto:
        # the search starts from the fewest steps the boxes allow (and every fixed sample)
        least = int(max(3, math.ceil(need[worst_vehicle, worst_axis] / dt - 1e-9) + 1,
                        fixed_steps))
        if least > steps:
            raise ScenarioError(
                "max_horizon",
                f"{steps * dt:g} s ({steps} steps of dt) is too short: vehicles[{culprit}]"
                f"{assigned} {why}, so the horizon needs at least {least} steps "
                f"({least * dt:g} s); raise max_horizon (at most {MAX_STEPS} steps)")
        return least
    if need[worst_vehicle, worst_axis] > usable + 1e-9:
        raise ScenarioError(
            f"vehicles[{culprit}].goal",
            f"cannot be reached within the horizon{assigned}: {why}; the horizon is "
            f"{horizon:.2f} s (steps * dt)",
        )
    return steps


def _steps_within(seconds: float, dt: float) -> int:
    """The most whole steps of `dt` in `seconds`, at most `MAX_STEPS`."""
    return min(MAX_STEPS, math.floor(seconds / dt + 1e-9))


def _steps_setting(data: Mapping[str, Any], dt: float) -> tuple[int, bool, float | None]:
    """(steps, steps_auto, max_horizon) from `steps` and `max_horizon`: an integer K, or
    "auto" with the most steps the search may try (`max_horizon` / dt, default
    `DEFAULT_MAX_HORIZON`)."""
    raw = data["steps"]
    if not isinstance(raw, str):
        if "max_horizon" in data:
            raise ScenarioError("max_horizon", f'applies only with steps "{AUTO_STEPS}": '
                                               f'remove it, or set steps to "{AUTO_STEPS}"')
        return _integer(raw, "steps", 3, MAX_STEPS), False, None
    if raw != AUTO_STEPS:
        shown = raw if len(raw) <= 20 else raw[:20] + "..."
        raise ScenarioError("steps", f'must be an integer from 3 to {MAX_STEPS} or '
                                     f'"{AUTO_STEPS}" (the planner chooses), got {shown!r}')
    max_horizon = check_number(data.get("max_horizon", DEFAULT_MAX_HORIZON), "max_horizon",
                               positive=True)
    if max_horizon > MAX_HORIZON_LIMIT:
        raise ScenarioError("max_horizon", f"must be at most {MAX_HORIZON_LIMIT:g} s, got "
                                           f"{max_horizon:g}")
    if max_horizon < 3 * dt - 1e-9:
        raise ScenarioError("max_horizon", f"must be at least 3 steps of dt = {dt:g} s "
                                           f"({3 * dt:g} s), got {max_horizon:g}")
    return _steps_within(max_horizon, dt), True, max_horizon


def _start_state(raw: Mapping[str, Any], where: str, limits: Limits
                 ) -> tuple[FloatArray | None, FloatArray | None]:
    """A vehicle's optional `start_velocity` and `start_acceleration`, each finite and inside
    the scenario's velocity / acceleration box (a start outside it cannot be planned from)."""
    out: list[FloatArray | None] = []
    for key, box, unit in (("start_velocity", limits.velocity_max, "m/s"),
                           ("start_acceleration", limits.acceleration_max, "m/s^2")):
        if raw.get(key) is None:
            out.append(None)
            continue
        value = check_vector(raw[key], f"{where}.{key}")
        if box is not None and np.any(np.abs(value) > box):
            axis = int(np.argmax(np.abs(value) - box))
            raise ScenarioError(f"{where}.{key}",
                                f"{value[axis]:g} {unit} on axis {'xyz'[axis]} exceeds the "
                                f"limit {box[axis]:g} {unit}")
        out.append(value)
    return out[0], out[1]


def _stack_given(values: list[FloatArray | None]) -> FloatArray | None:
    """(N, 3) of the given vectors (zeros where omitted), or None when none was given."""
    if all(x is None for x in values):
        return None
    return np.array([np.zeros(3) if x is None else x for x in values])
