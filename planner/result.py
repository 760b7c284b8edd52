"""The plan (the output JSON contract): trajectories, cost history, timings, verification.

Long: the plan contract: its dataclasses and the reader that checks every field.

`Plan.to_dict()` produces the Plan JSON of docs/development/architecture.md (and the README);
`Plan.from_dict()` reads it back (for the GCS, the API and tests) and checks shapes, raising
`PlanFormatError` naming the field.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
from enum import StrEnum
from typing import Any, TextIO

import numpy as np
import orjson
from numpy.typing import NDArray

from planner.errors import PlanFormatError, ScenarioError
from planner.model.dynamics import MotionSample, interpolate
from planner.model.flatness import thrust_cost
from planner.model.scenario import Scenario
from planner.types import FloatArray
from planner.verification.ground import starts_on_the_ground

__all__ = [
    "OUTCOMES",
    "STATUSES",
    "Attempt",
    "IterationProgress",
    "IterationRecord",
    "Outcome",
    "Plan",
    "PlanStatus",
    "Progress",
    "VehicleTrajectory",
    "Verification",
]


class PlanStatus(StrEnum):
    """Every status a plan can carry (the JSON strings are the values). `unverified`: the
    loop stopped but the independent verification failed (reported rather than hidden)."""

    CONVERGED = "converged"
    MAX_ITERATIONS = "max_iterations"
    INFEASIBLE = "infeasible"
    UNVERIFIED = "unverified"


#: The plan statuses as JSON strings, in the order of `PlanStatus`.
STATUSES = tuple(status.value for status in PlanStatus)


class Outcome(StrEnum):
    """What became of one planning method (`Attempt.outcome`)."""

    WON = "won"
    """It produced the plan."""
    DECLINED = "declined"
    """It did not apply to the scenario and did not run."""
    FAILED = "failed"
    """It ran and gave no converged, verified plan."""
    CANCELLED = "cancelled"
    """It was stopped because another method's plan came first."""


#: The attempt outcomes as JSON strings.
OUTCOMES = tuple(outcome.value for outcome in Outcome)


@dataclass(frozen=True)
class Attempt:
    """One planning method tried or declined on the way to a plan (`planner.methods.stages`)."""

    method: str
    """The method (stage): separated_first, prioritized, dodge or whole."""
    outcome: str
    """won, declined, failed or cancelled (`Outcome`)."""
    reason: str
    """Why it was declined, failed or cancelled; how it won."""
    seconds: float
    """Wall time it took (s); 0 for a declined one that cost nothing measurable."""


@dataclass(frozen=True)
class VehicleTrajectory:
    """One vehicle's planned motion on the step grid (world frame ENU, SI units)."""

    id: str
    t: FloatArray
    """(K+1,) step times from 0 to K*dt (s)."""
    position: FloatArray
    """(K+1, 3) positions at the steps (m)."""
    velocity: FloatArray
    """(K+1, 3) velocities at the steps (m/s)."""
    acceleration: FloatArray
    """(K, 3) accelerations, constant over each step (m/s^2)."""
    jerk: FloatArray
    """(K, 3) jerk (a[k] - a[k-1]) / dt with a[-1] the vehicle's start acceleration (0: it
    starts hovering) (m/s^3)."""
    thrust: FloatArray
    """(K,) mass-normalised thrust ||a + g|| (m/s^2), paper eq. 14."""
    body_rates: FloatArray
    """(K, 3) body rates (w1, w2, w3) from the jerk, w3 = 0 (rad/s), paper eq. 20."""

    def sample(self, dt: float, times: Any) -> MotionSample:
        """The exact motion at arbitrary times (see `planner.model.dynamics.interpolate`)."""
        return interpolate(self.position, self.velocity, self.acceleration, dt, times)

    def json_text(self) -> str:
        """JSON text of `to_dict()`, the arrays serialised from numpy by orjson (the same
        numbers; a non-finite one becomes null, which a plan reader refuses)."""
        return orjson.dumps(
            {"id": self.id, **{key: np.ascontiguousarray(getattr(self, key), dtype=np.float64)
                               for key in _TRAJECTORY_ARRAYS}},
            option=orjson.OPT_SERIALIZE_NUMPY).decode()

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, **{key: getattr(self, key).tolist() for key in _TRAJECTORY_ARRAYS}}


#: A vehicle trajectory's arrays, in the order of its JSON document.
_TRAJECTORY_ARRAYS = ("t", "position", "velocity", "acceleration", "jerk", "thrust",
                      "body_rates")


@dataclass(frozen=True)
class IterationRecord:
    """One SCP iteration (iteration 0 is the separation-free first QP)."""

    iteration: int
    cost: float
    """Total thrust cost sum ||a + g||^2 after this iteration."""
    cost_change: float | None
    """|cost - previous cost|, None for iteration 0."""
    separation_rows: int
    """Separation rows in this iteration's QPs (after any lazily added rows)."""
    qp_solves: int
    """QP solves in this iteration (sub-problems and re-solves for added rows)."""
    groups: int
    """Independent sub-problems (groups of vehicles linked by candidate pairs)."""
    seconds: float
    largest_group: int = 0
    """Vehicles in the largest group."""
    method: str | None = None
    """The planning method whose iteration this is (`Attempt.method`); null in plans
    written without it."""
    batch: int | None = None
    """With prioritized batches, the batch (from 1) whose iteration this is; null otherwise."""
    batches: int | None = None
    """With prioritized batches, how many batches the plan has when this one started
    (a batch deferred to the end of the order counts again); null otherwise."""


@dataclass(frozen=True)
class IterationProgress:
    """Work done so far inside a long SCP iteration, given to `progress` between the
    iteration records (at most once a second; never part of a plan): a sign of life while
    a crowd's QPs take minutes."""

    iteration: int
    """The iteration under way (1 is the first with separation rows)."""
    round: int
    """Its solve round (from 1): each round after the first adds the rows the last broke."""
    groups_done: int
    """Groups of this round solved so far."""
    groups: int
    """Groups in this round."""
    separation_rows: int
    """Separation rows in this round's QPs."""
    largest_group: int
    """Vehicles in this round's largest group (its QP is the longest)."""
    qp_solves: int
    """QP solves in this iteration so far."""
    seconds: float
    """Seconds since the iteration began."""
    method: str | None = None
    """As `IterationRecord.method`."""
    batch: int | None = None
    """As `IterationRecord.batch`."""
    batches: int | None = None
    """As `IterationRecord.batches`."""


#: What the planner's methods report progress to: every iteration's record, and within long
#: iterations their progress (`planner.plan` hands each kind to its own callback).
Progress = Callable[[IterationRecord | IterationProgress], None]


#: Field metadata of the verification's obstacle figures: the plan JSON leaves them out
#: for a scenario without obstacles (such plans carry no obstacle keys at all), and the
#: published schema does not require them.
_OBSTACLE_FIELD: dict[str, Any] = {"omitted": "without obstacles"}
#: The same for the figures of fixed trajectories (`planner.model.fixed`).
_FIXED_FIELD: dict[str, Any] = {"omitted": "without fixed trajectories"}


@dataclass(frozen=True)
class Verification:
    """Checks of the final trajectories, computed independently of the solver."""

    min_separation: float | None
    """Smallest pair distance at the steps, in the separation metric (m); None with one
    vehicle, or when it is undefined (non-finite motion, an overflowing metric)."""
    min_separation_continuous: float | None
    """Smallest pair distance over continuous time, exact motion between steps (m); None
    as for min_separation."""
    closest_pair: list[str]
    """The two vehicle ids of the continuous-time minimum (empty when there is none)."""
    closest_time: float
    """When the continuous-time minimum happens (s)."""
    max_violation: dict[str, float | None]
    """Largest excess over each bound group (position, velocity, acceleration, jerk, ...);
    None where it cannot be computed (non-finite motion)."""
    boundary_error: dict[str, float | None]
    """Largest error of each boundary condition (start/goal position, velocities, accel);
    None where it cannot be computed."""
    thrust_range: list[float | None]
    """[min, max] thrust over all vehicles and steps (m/s^2); None where undefined."""
    body_rate_peak: float | None
    """Largest |w1| or |w2| over all vehicles and steps (rad/s); None where undefined."""
    flyable: bool
    """Thrust within [thrust_min, thrust_max] and body rates under body_rate_max."""
    separated: bool
    """Continuous-time separation >= R - separation_tolerance (false when undefined)."""
    within_bounds: bool
    """Every box and boundary condition holds within bound_tolerance."""
    separation_tolerance: float
    bound_tolerance: float
    obstacle_distance_min: float | None = field(default=None, metadata=_OBSTACLE_FIELD)
    """Smallest distance of any vehicle to any obstacle's solid over continuous time (m;
    negative inside one); absent without obstacles, null when undefined."""
    closest_obstacle: dict[str, Any] | None = field(default=None, metadata=_OBSTACLE_FIELD)
    """Where that happens: {"id": obstacle id, "vehicle": vehicle id, "time": s}; absent
    without obstacles."""
    clear: bool = field(default=True, metadata=_OBSTACLE_FIELD)
    """obstacle_distance_min >= obstacle_clearance - separation_tolerance; absent (true)
    without obstacles, false when undefined."""
    fixed_distance_min: float | None = field(default=None, metadata=_FIXED_FIELD)
    """Smallest distance (separation metric, m) of a planned vehicle from a fixed one
    (`planner.model.fixed`) over continuous time, the pair with the least slack against R plus
    the fixed one's margin; absent without fixed trajectories, null when undefined."""
    closest_fixed: dict[str, Any] | None = field(default=None, metadata=_FIXED_FIELD)
    """Where: {"id": fixed id, "vehicle": planned id, "time": s, "required": R + margin};
    empty when undefined; absent without fixed trajectories."""

    @property
    def verified(self) -> bool:
        """Separated, clear of the obstacles, within bounds, and flyable (thrust and body
        rates within limits)."""
        return self.separated and self.clear and self.within_bounds and self.flyable

    def to_dict(self) -> dict[str, Any]:
        """The JSON form; the obstacle fields only for a scenario with obstacles."""
        out = asdict(self)
        for f in fields(self):
            omitted = f.metadata.get("omitted")
            obstacle_unused = (omitted == _OBSTACLE_FIELD["omitted"]
                               and self.closest_obstacle is None and self.clear)
            fixed_unused = omitted == _FIXED_FIELD["omitted"] and self.closest_fixed is None
            if obstacle_unused or fixed_unused:
                del out[f.name]
        return out

    def failures(self) -> list[str]:
        """What failed, in words (empty when verified)."""
        out = []
        near = self.closest_fixed
        fixed_failed = near is not None and (
            self.fixed_distance_min is None or not near
            or self.fixed_distance_min < near["required"] - self.separation_tolerance)
        if fixed_failed:
            assert near is not None
            out.append("distance from the fixed trajectories is undefined (non-finite motion)"
                       if not near or self.fixed_distance_min is None else
                       f"vehicle {near['vehicle']!r} comes {self.fixed_distance_min:.4f} m "
                       f"from fixed vehicle {near['id']!r} at {near['time']:.2f} s, under "
                       f"{near['required']:g} m")
        if not self.separated and not fixed_failed:
            if self.min_separation_continuous is None:
                out.append("continuous-time separation is undefined (non-finite motion or "
                           "an overflowing separation metric)")
            else:
                out.append(f"continuous-time separation {self.min_separation_continuous:.4f} m "
                           f"is below R")
        if not self.clear:
            near = self.closest_obstacle or {}
            out.append("obstacle clearance undefined (non-finite motion)"
                       if self.obstacle_distance_min is None else
                       f"vehicle {near.get('vehicle')!r} comes {self.obstacle_distance_min:.4f} m "
                       f"from obstacle {near.get('id')!r} at {near.get('time', 0.0):.2f} s, "
                       f"under the clearance")
        if not self.within_bounds:
            errors = {**self.max_violation, **self.boundary_error}
            undefined = [key for key, x in errors.items() if x is None]
            if undefined:
                out.append(f"{', '.join(undefined)} undefined (non-finite motion)")
            else:
                key, worst = max(errors.items(), key=lambda kv: kv[1] or 0.0)
                out.append(f"{key} off by {worst:.3g}")
        if not self.flyable:
            out.append(f"not flyable: thrust {_figure(self.thrust_range[0], '.2f')}..."
                       f"{_figure(self.thrust_range[1], '.2f')} m/s^2, body rate peak "
                       f"{_figure(self.body_rate_peak, '.2f')} rad/s against the limits")
        return out


def _figure(x: float | None, fmt: str) -> str:
    """A figure for a message: 'undefined' for None."""
    return "undefined" if x is None else format(x, fmt)


@dataclass(frozen=True)
class Plan:
    """The planner's result. `status` is one of `STATUSES`."""

    status: str
    message: str
    scenario: Scenario
    vehicles: tuple[VehicleTrajectory, ...]
    iterations: tuple[IterationRecord, ...]
    timing: dict[str, float]
    verification: Verification | None
    solver: str
    infeasible_groups: tuple[str, ...] = field(default=())
    """For `infeasible`: which constraint group(s) could not be met, as far as known."""
    sequence: dict[str, Any] | None = None
    """For a stitched formation sequence: its formations, slots, timeline and legs summary
    (`planner.methods.sequence`); None (JSON null) for a single scenario's plan."""
    horizon: dict[str, Any] | None = None
    """For `steps: "auto"`: how the horizon was chosen (`planner.methods.horizon_search`: the
    candidates tried, the chosen steps); None (JSON null) for a fixed number of steps."""
    method: str | None = None
    """The planning method that produced the plan (`Attempt.method`); null for a stitched
    sequence (its legs say) and in plans written without it."""
    attempts: tuple[Attempt, ...] = ()
    """Every method tried or declined, in order, with its outcome, reason and time."""

    @property
    def ok(self) -> bool:
        """A converged plan whose verification passed (`problems` is empty)."""
        return not self.problems()

    def problems(self) -> list[str]:
        """Why the plan is not verified, in words; empty for a converged plan whose
        verification passed. The one verdict `ok`, the CLI table and its exit status use."""
        out = []
        if self.status != "converged":
            out.append(f"status {self.status}" + (f": {self.message}" if self.message else ""))
        if self.verification is None:
            out.append("no verification")
        else:
            out += [f for f in self.verification.failures() if f not in self.message]
        return out

    @property
    def cost(self) -> float:
        """The plan's total-thrust cost sum ||a + g||^2 over every vehicle and step, from its
        trajectories (the last iteration's cost is only its batch's with prioritized
        batches); nan for a plan without vehicles."""
        return thrust_cost(self.accelerations()) if self.vehicles else float("nan")

    def positions(self) -> FloatArray:
        """(N, K+1, 3) positions of all vehicles."""
        return np.stack([v.position for v in self.vehicles])

    def velocities(self) -> FloatArray:
        return np.stack([v.velocity for v in self.vehicles])

    def accelerations(self) -> FloatArray:
        return np.stack([v.acceleration for v in self.vehicles])

    def sample(self, times: Any) -> MotionSample:
        """Every vehicle's exact motion at `times`: arrays (N, M, 3)."""
        return interpolate(
            self.positions(), self.velocities(), self.accelerations(), self.scenario.dt, times
        )

    def to_dict(self) -> dict[str, Any]:
        return self._document([v.to_dict() for v in self.vehicles])

    def write_json(self, stream: TextIO) -> None:
        """Write the document of `to_dict()` as JSON text to `stream`, one vehicle at a time
        and its arrays straight from numpy (`VehicleTrajectory.json_text`): a show-scale plan
        (16,000 vehicles) never holds all its numbers as Python objects, which would take
        gigabytes and most of a minute."""
        stream.write("{")
        for n, (key, value) in enumerate(self._document([]).items()):
            stream.write((", " if n else "") + json.dumps(key) + ": ")
            if key != "vehicles":  # orjson: a non-finite number becomes null (strict JSON)
                stream.write(orjson.dumps(value).decode())
                continue
            stream.write("[")
            for m, vehicle in enumerate(self.vehicles):
                stream.write((", " if m else "") + vehicle.json_text())
            stream.write("]")
        stream.write("}")

    def _document(self, vehicles: list[dict[str, Any]]) -> dict[str, Any]:
        """The plan's JSON document with `vehicles` as its vehicle list."""
        return {
            "status": self.status,
            "message": self.message,
            "solver": self.solver,
            "infeasible_groups": list(self.infeasible_groups),
            "scenario": self.scenario.to_dict(),
            "iterations": [asdict(r) for r in self.iterations],
            "timing": dict(self.timing),
            "vehicles": vehicles,
            "verification": None if self.verification is None else self.verification.to_dict(),
            "assignment": {v.id: int(g) for v, g in zip(self.scenario.vehicles,
                                                        self.scenario.order, strict=True)},
            "sequence": self.sequence,
            "horizon": self.horizon,
            "method": self.method,
            "attempts": [asdict(attempt) for attempt in self.attempts],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Plan:
        """Read a Plan JSON document back; raises `PlanFormatError` naming the field."""
        return _plan_from_dict(data)


def _array(data: Mapping[str, Any], key: str, where: str, shape: tuple[int, ...]) -> FloatArray:
    if key not in data:
        raise PlanFormatError(f"{where}.{key}", "is required")
    try:
        arr = np.asarray(data[key], dtype=float)
    except (TypeError, ValueError) as exc:
        raise PlanFormatError(f"{where}.{key}", f"must be numeric: {exc}") from None
    if arr.shape != shape:
        raise PlanFormatError(f"{where}.{key}", f"must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise PlanFormatError(f"{where}.{key}", "must contain finite numbers only")
    return arr


def _list(value: Any, where: str) -> list[Any]:
    if not isinstance(value, list):
        raise PlanFormatError(where, "must be a list")
    return value


def _record(cls: Any, value: Any, where: str) -> Any:
    """A dataclass from a JSON object, with unknown or missing keys named."""
    if not isinstance(value, Mapping):
        raise PlanFormatError(where, "must be a JSON object")
    names = {f.name for f in fields(cls)}
    for key in value:
        if key not in names:
            raise PlanFormatError(f"{where}.{key}", "unknown key")
    try:
        return cls(**value)
    except TypeError as exc:
        raise PlanFormatError(where, str(exc).split("__init__() ")[-1]) from None


def _assignment(value: Any, scenario: Scenario) -> NDArray[np.intp] | None:
    """The plan's `assignment` {vehicle id: goal index}, checked to be a permutation (the
    identity for a fixed scenario)."""
    if not isinstance(value, Mapping):
        raise PlanFormatError("assignment", "must be a JSON object {vehicle id: goal index}")
    n = len(scenario.vehicles)
    order = np.empty(n, dtype=np.intp)
    for index, vehicle in enumerate(scenario.vehicles):
        goal = value.get(vehicle.id)
        if isinstance(goal, bool) or not isinstance(goal, int) or not 0 <= goal < n:
            raise PlanFormatError(f"assignment.{vehicle.id}",
                                  f"must be a goal index 0..{n - 1}, got {goal!r}")
        order[index] = goal
    if len(value) != n or len(np.unique(order)) != n:
        raise PlanFormatError("assignment", "must give each vehicle a different goal")
    if scenario.assignment == "fixed":
        if np.any(order != np.arange(n)):
            raise PlanFormatError("assignment", "must be the identity for a fixed assignment")
        return None
    return order


def _plan_from_dict(data: Mapping[str, Any]) -> Plan:
    if not isinstance(data, Mapping):
        raise PlanFormatError("plan", "must be a JSON object")
    for key in ("status", "scenario", "vehicles"):
        if key not in data:
            raise PlanFormatError(key, "is required")
    status = data["status"]
    if status not in STATUSES:
        raise PlanFormatError("status", f"must be one of {', '.join(STATUSES)}, got {status!r}")
    try:
        scenario = Scenario.from_dict(data["scenario"],
                                      on_ground=starts_on_the_ground(data.get("sequence")))
    except ScenarioError as exc:
        raise PlanFormatError(f"scenario.{exc.field}", exc.reason) from None
    if "assignment" in data:
        scenario = dataclasses.replace(
            scenario, goal_order=_assignment(data["assignment"], scenario))
    k = scenario.steps
    raw_vehicles = data["vehicles"]
    if not isinstance(raw_vehicles, list) or len(raw_vehicles) != len(scenario.vehicles):
        raise PlanFormatError("vehicles", f"must list {len(scenario.vehicles)} vehicles")
    vehicles = []
    for index, (raw, spec) in enumerate(zip(raw_vehicles, scenario.vehicles, strict=True)):
        where = f"vehicles[{index}]"
        if not isinstance(raw, Mapping):
            raise PlanFormatError(where, "must be a JSON object")
        if raw.get("id") != spec.id:
            raise PlanFormatError(f"{where}.id", f"must be {spec.id!r} (scenario order)")
        vehicles.append(
            VehicleTrajectory(
                id=spec.id,
                t=_array(raw, "t", where, (k + 1,)),
                position=_array(raw, "position", where, (k + 1, 3)),
                velocity=_array(raw, "velocity", where, (k + 1, 3)),
                acceleration=_array(raw, "acceleration", where, (k, 3)),
                jerk=_array(raw, "jerk", where, (k, 3)),
                thrust=_array(raw, "thrust", where, (k,)),
                body_rates=_array(raw, "body_rates", where, (k, 3)),
            )
        )
    iterations = tuple(_record(IterationRecord, r, f"iterations[{n}]")
                       for n, r in enumerate(_list(data.get("iterations", []), "iterations")))
    raw_verification = data.get("verification")
    verification = (None if raw_verification is None
                    else _record(Verification, raw_verification, "verification"))
    raw_timing = data.get("timing", {})
    if not isinstance(raw_timing, Mapping):
        raise PlanFormatError("timing", "must be a JSON object")
    timing = {}
    for key, value in raw_timing.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise PlanFormatError(f"timing.{key}", "must be a number")
        timing[str(key)] = float(value)
    return Plan(
        status=status,
        message=str(data.get("message", "")),
        scenario=scenario,
        vehicles=tuple(vehicles),
        iterations=iterations,
        timing=timing,
        verification=verification,
        solver=str(data.get("solver", "")),
        infeasible_groups=tuple(data.get("infeasible_groups", ())),
        sequence=_sequence_block(data.get("sequence")),
        horizon=_horizon_block(data.get("horizon")),
        method=_method(data.get("method")),
        attempts=tuple(_attempt(r, f"attempts[{n}]")
                       for n, r in enumerate(_list(data.get("attempts", []), "attempts"))),
    )


def _method(value: Any) -> str | None:
    """The plan's optional `method`: a string or null."""
    if value is not None and not isinstance(value, str):
        raise PlanFormatError("method", f"must be a string or null, got {value!r}")
    return value


def _attempt(value: Any, where: str) -> Attempt:
    """One `attempts` entry, its outcome checked."""
    attempt: Attempt = _record(Attempt, value, where)
    if attempt.outcome not in OUTCOMES:
        raise PlanFormatError(f"{where}.outcome", f"must be one of {', '.join(OUTCOMES)}, "
                                                  f"got {attempt.outcome!r}")
    return attempt


def _sequence_block(value: Any) -> dict[str, Any] | None:
    """The optional `sequence` block of a stitched sequence's plan, kept as given."""
    if value is None:
        return None
    if not isinstance(value, Mapping):
        raise PlanFormatError("sequence", "must be a JSON object")
    return dict(value)


def _horizon_block(value: Any) -> dict[str, Any] | None:
    """The optional `horizon` block of a plan whose horizon was searched, kept as given."""
    if value is not None and not isinstance(value, Mapping):
        raise PlanFormatError("horizon", "must be a JSON object")
    return None if value is None else dict(value)
