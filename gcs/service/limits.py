"""Work bounds: every scenario quantity that multiplies the service's work or memory.

A plan's size, its flight's length and its exports grow with vehicles x steps, the horizon
(dt x steps) and the magnitude of its coordinates; one absurd value (dt = 1e8, a workspace
corner at 1e308) would exhaust memory, overflow the simulator or put Infinity into JSON. These
checks run on the raw scenario JSON before the planner allocates anything, report every
bound exceeded at once, and name the field and the setting that sets the bound. Problems of
type or meaning (a string for dt, a negative dt) are left to the scenario's own validation.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gcs.errors import InvalidRequest
from gcs.replan_request import MAX_ENTRIES as MAX_REPLAN_ENTRIES
from gcs.service.events import MAX_BACKLOG
from gcs.service.settings import Settings
from planner.model.scenario import AUTO_STEPS, DEFAULT_MAX_HORIZON

__all__ = [
    "FIXED_LIMITS",
    "LIMIT_NAMES",
    "MAX_SEQUENCE_LEGS",
    "MIN_STEPS",
    "WorkBounds",
    "limits_in_force",
    "scenario_bound_errors",
    "sequence_bound_errors",
    "trajectory_sample_count",
    "with_server_horizon",
]

#: Most legs (formations after the first) one sequence request may ask for.
MAX_SEQUENCE_LEGS = 20
#: Fewest `steps` a scenario may have (the planner's own minimum).
MIN_STEPS = 3
#: The settings that bound a request, as `GET /api/status` publishes them (``limits``).
LIMIT_NAMES: tuple[str, ...] = (
    "max_vehicles", "max_steps", "max_obstacles", "dt_min", "dt_max", "max_horizon_s",
    "max_coordinate_m", "max_body_bytes", "max_plan_body_bytes", "max_trajectory_rate",
    "max_trajectory_samples",
    "plan_queue_max", "plan_time_limit_s", "request_timeout_s", "idle_timeout_s",
    "max_concurrent_exports", "max_event_streams", "max_event_streams_per_resource",
)


#: The fixed limits (not settings) `GET /api/status` publishes beside `LIMIT_NAMES`.
FIXED_LIMITS: dict[str, int] = {
    "max_sequence_legs": MAX_SEQUENCE_LEGS,
    "max_replan_entries": MAX_REPLAN_ENTRIES,  # vehicles one replan names in goals, in drop
    "max_event_backlog": MAX_BACKLOG,  # events an event stream may fall behind before it ends
}


def limits_in_force(settings: Settings) -> dict[str, int | float]:
    """Every limit a request is checked against, by name: the settings of `LIMIT_NAMES` and
    the `FIXED_LIMITS`."""
    limits: dict[str, int | float] = {name: getattr(settings, name) for name in LIMIT_NAMES}
    limits.update(FIXED_LIMITS)
    return limits


@dataclass(frozen=True)
class WorkBounds:
    """The bounds, from the settings of the same names."""

    max_vehicles: int
    max_steps: int
    dt_min: float
    dt_max: float
    max_horizon_s: float
    max_coordinate_m: float
    max_obstacles: int = 1000

    @classmethod
    def from_settings(cls, settings: Settings) -> WorkBounds:
        return cls(
            max_vehicles=settings.max_vehicles, max_steps=settings.max_steps,
            dt_min=settings.dt_min, dt_max=settings.dt_max,
            max_horizon_s=settings.max_horizon_s, max_coordinate_m=settings.max_coordinate_m,
            max_obstacles=settings.max_obstacles,
        )


def _real(value: Any) -> float | None:
    """A JSON number as a float, None for anything else (left to the scenario's checks)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _points(data: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """Every coordinate vector of the scenario, by dotted path."""
    out: list[tuple[str, Any]] = []
    limits = data.get("limits")
    if isinstance(limits, Mapping):
        out += [(f"limits.{key}", limits.get(key)) for key in ("position_min", "position_max")]
    vehicles = data.get("vehicles")
    if isinstance(vehicles, list):
        for index, vehicle in enumerate(vehicles):
            if isinstance(vehicle, Mapping):
                out += [(f"vehicles[{index}].{key}", vehicle.get(key))
                        for key in ("start", "goal")]
    obstacles = data.get("obstacles")
    if isinstance(obstacles, list):
        # At most the planner's cap (it refuses longer lists); 64 vertices a polygon likewise.
        for index, obstacle in enumerate(obstacles[:1000]):
            if not isinstance(obstacle, Mapping):
                continue
            for kind, keys in (("box", ("min", "max")), ("cylinder", ("center", "z")),
                               ("prism", ("z",))):
                shape = obstacle.get(kind)
                if isinstance(shape, Mapping):
                    out += [(f"obstacles[{index}].{kind}.{key}", shape.get(key)) for key in keys]
                    polygon = shape.get("polygon") if kind == "prism" else None
                    if isinstance(polygon, list):
                        out += [(f"obstacles[{index}].prism.polygon[{n}]", vertex)
                                for n, vertex in enumerate(polygon[:64])]
    return out


def scenario_bound_errors(data: Mapping[str, Any], bounds: WorkBounds) -> list[InvalidRequest]:
    """Every bound the scenario JSON exceeds (empty when it fits)."""
    errors: list[InvalidRequest] = []
    errors += _vehicle_count_errors(data, bounds)
    obstacles = data.get("obstacles")
    if isinstance(obstacles, list) and len(obstacles) > bounds.max_obstacles:
        errors.append(InvalidRequest(
            "obstacles", f"{len(obstacles)} obstacles exceed this server's limit of "
            f"{bounds.max_obstacles} (setting max_obstacles)"))
    steps = _real(data.get("steps"))
    if steps is not None and steps > bounds.max_steps:
        errors.append(InvalidRequest(
            "steps", f"{steps:g} steps exceed this server's limit of {bounds.max_steps} "
            f"(setting max_steps)"))
    elif steps is not None and steps < MIN_STEPS:
        errors.append(InvalidRequest(
            "steps", f"must be between {MIN_STEPS} and {bounds.max_steps} on this server, "
            f"got {steps:g} (setting max_steps)"))
    dt = _real(data.get("dt"))
    dt_errors = _dt_errors(dt, bounds)
    errors += dt_errors
    if data.get("steps") == AUTO_STEPS and not dt_errors:
        errors += _max_horizon_errors(_real(data.get("max_horizon")), 1, 0.0, dt, bounds)
    if not dt_errors and dt is not None and dt > 0 and steps is not None and steps > 0:
        horizon = dt * steps
        if horizon > bounds.max_horizon_s:
            errors.append(InvalidRequest(
                "steps", f"the horizon steps * dt = {horizon:g} s exceeds this server's limit "
                f"of {bounds.max_horizon_s:g} s (setting max_horizon_s)"))
    return errors + _coordinate_errors(_points(data), bounds)


def _vehicle_count_errors(data: Mapping[str, Any], bounds: WorkBounds) -> list[InvalidRequest]:
    """More vehicles than `max_vehicles`."""
    vehicles = data.get("vehicles")
    if isinstance(vehicles, list) and len(vehicles) > bounds.max_vehicles:
        return [InvalidRequest("vehicles", f"{len(vehicles)} vehicles exceed this server's "
                               f"limit of {bounds.max_vehicles} (setting max_vehicles)")]
    return []


def _dt_errors(dt: float | None, bounds: WorkBounds) -> list[InvalidRequest]:
    """A step length outside [dt_min, dt_max] (a non-positive one is the planner's to name)."""
    if dt is not None and dt > 0 and not bounds.dt_min <= dt <= bounds.dt_max:
        return [InvalidRequest("dt", f"must be between {bounds.dt_min:g} and "
                               f"{bounds.dt_max:g} s on this server, got {dt:g} "
                               f"(settings dt_min, dt_max)")]
    return []


def _coordinate_errors(points: list[tuple[str, Any]], bounds: WorkBounds
                       ) -> list[InvalidRequest]:
    """Every coordinate farther than `max_coordinate_m` from the origin, each named."""
    errors = []
    for where, point in points:
        if not isinstance(point, list):
            continue
        for axis, component in enumerate(point):
            x = _real(component)
            if x is not None and math.isfinite(x) and abs(x) > bounds.max_coordinate_m:
                errors.append(InvalidRequest(
                    f"{where}[{axis}]", f"{x:g} m is farther than {bounds.max_coordinate_m:g} m "
                    f"from the origin (setting max_coordinate_m)"))
    return errors


def sequence_bound_errors(data: Mapping[str, Any], bounds: WorkBounds) -> list[InvalidRequest]:
    """Every bound a formation sequence JSON exceeds: vehicles, legs, dt, the whole timeline
    (steps and seconds: it is flown as one plan), coordinates. Empty when it fits."""
    errors: list[InvalidRequest] = []
    errors += _vehicle_count_errors(data, bounds)
    formations = data.get("formations")
    formations = formations if isinstance(formations, list) else []
    if len(formations) - 1 > MAX_SEQUENCE_LEGS:
        errors.append(InvalidRequest(
            "formations", f"{len(formations) - 1} legs exceed this server's limit of "
            f"{MAX_SEQUENCE_LEGS}"))
    dt = _real(data.get("dt"))
    errors += _dt_errors(dt, bounds)
    autos, seconds = _timeline(formations)
    if autos:
        errors += _max_horizon_errors(_real(data.get("max_horizon")), autos, seconds, dt,
                                      bounds)
    points: list[tuple[str, Any]] = []
    limits = data.get("limits")
    if isinstance(limits, Mapping):
        points += [(f"limits.{key}", limits.get(key)) for key in ("position_min", "position_max")]
    for f, formation in enumerate(formations):
        if not isinstance(formation, Mapping):
            continue
        positions = formation.get("positions")
        if isinstance(positions, list):
            points += [(f"formations[{f}].positions[{n}]", p) for n, p in enumerate(positions)]
    if seconds > bounds.max_horizon_s:
        errors.append(InvalidRequest(
            "formations", f"the sequence lasts {seconds:g} s (durations and holds), more than "
            f"this server's limit of {bounds.max_horizon_s:g} s (setting max_horizon_s)"))
    elif dt is not None and dt > 0 and seconds / dt > bounds.max_steps + 0.5:
        errors.append(InvalidRequest(
            "formations", f"the sequence lasts {seconds / dt:.0f} steps of dt, more than this "
            f"server's limit of {bounds.max_steps} (setting max_steps)"))
    return errors + _coordinate_errors(points, bounds)


def _timeline(formations: list[Any]) -> tuple[int, float]:
    """(formations of duration "auto", seconds of the other durations and every hold)."""
    autos, seconds = 0, 0.0
    for formation in formations:
        if not isinstance(formation, Mapping):
            continue
        autos += formation.get("duration") == AUTO_STEPS
        for key in ("duration", "hold"):
            value = _real(formation.get(key))
            if value is not None and math.isfinite(value) and value > 0:
                seconds += value
    return autos, seconds


def _budget(dt: float, bounds: WorkBounds) -> float:
    """The longest timeline this server plans at step `dt` (s)."""
    return min(bounds.max_horizon_s, bounds.max_steps * dt)


def _max_horizon_errors(given: float | None, autos: int, seconds: float, dt: float | None,
                        bounds: WorkBounds) -> list[InvalidRequest]:
    """A `max_horizon` whose `autos` searched horizons, after `seconds` of fixed timeline,
    could exceed this server's horizon or steps (none given: `with_server_horizon` sets it)."""
    if given is None or not math.isfinite(given) or dt is None or dt <= 0:
        return []
    if seconds + autos * given <= _budget(dt, bounds) + 1e-9:
        return []
    room = max(0.0, (_budget(dt, bounds) - seconds) / autos)
    return [InvalidRequest(
        "max_horizon", f"{given:g} s could take the plan past this server's limit of "
        f"{bounds.max_horizon_s:g} s and {bounds.max_steps} steps of dt (settings "
        f"max_horizon_s, max_steps); give at most {room:g} s")]


def with_server_horizon(data: Mapping[str, Any], bounds: WorkBounds) -> Mapping[str, Any]:
    """The request with the `max_horizon` this server allows when a horizon is "auto" (a
    scenario's steps, formations' durations) and it gives none: the planner's default, or
    less, so that the plan fits the horizon and steps limits (shared by a sequence's auto
    legs after its fixed durations and holds)."""
    dt = _real(data.get("dt"))
    if "max_horizon" in data or dt is None or dt <= 0:
        return data
    formations = data.get("formations")
    autos, seconds = (_timeline(formations) if isinstance(formations, list)
                      else (int(data.get("steps") == AUTO_STEPS), 0.0))
    if not autos:
        return data
    share = (_budget(dt, bounds) - seconds) / autos
    return {**data, "max_horizon": min(DEFAULT_MAX_HORIZON, share)}


def trajectory_sample_count(horizon: float, rate: float, vehicles: int) -> int:
    """How many vehicle-time samples an export at `rate` Hz holds, computed without
    allocating them (`gcs.service.plans.sample_times` makes the same count)."""
    if not math.isfinite(horizon * rate):
        return sys.maxsize
    times = math.floor(horizon * rate + 1e-9) + 1
    if horizon - (times - 1) / rate > 1e-9:
        times += 1
    return times * vehicles
