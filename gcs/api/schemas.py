"""The API's documents, derived from the planner's types so each field is declared once.

Long: the API's documents, a table of pydantic models derived from the planner's types.

The scenario and the plan are the planner's contracts (`planner.model.scenario`, `planner.result`).
`planner_schemas` turns those dataclasses into OpenAPI/JSON Schema components by reading their
fields, type hints, attribute docstrings and `planner.model.scenario.DEFAULTS`; nothing here repeats
a field. A scenario body is checked against that schema (`shape_errors`: every type, key and
length problem at once, named by dotted path) and then by `planner.Scenario.from_dict`, the one
definition of a valid scenario, which names the field of the first problem of meaning
(workspace, separation, reachability).

The mission documents (`MissionSummary`, `MissionOut`, ...) belong to the API and are pydantic
models; their `scenario`, `plan` and `progress` fields point at the planner-derived components.
"""

from __future__ import annotations

import ast
import collections.abc
import dataclasses
import inspect
import itertools
import json
import re
import threading
import types
import typing
from functools import cache
from importlib import resources
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, WithJsonSchema

from gcs.api.errors import ErrorItem
from gcs.service.statuses import MissionStatus
from planner import result as planner_result
from planner.model import fixed as planner_fixed
from planner.model import obstacles as planner_obstacles
from planner.model import scenario as planner_scenario
from planner.model.checks import unknown_key

__all__ = [
    "EXAMPLE_SCENARIO",
    "MissionList",
    "MissionOut",
    "MissionSummary",
    "TrajectoryOut",
    "planner_schemas",
    "ref",
    "shape_errors",
]


def _example_scenario() -> dict[str, Any]:
    text = resources.files("planner").joinpath("examples/paper-circle4.json").read_text()
    scenario: dict[str, Any] = json.loads(text)
    return scenario


#: The paper's 4-vehicle circle case, shown as the request example.
EXAMPLE_SCENARIO: dict[str, Any] = _example_scenario()

_ITERATION: dict[str, Any] = {
    "iteration": 1, "cost": 14433.1, "cost_change": 0.115, "separation_rows": 96,
    "qp_solves": 1, "groups": 2, "seconds": 0.02, "largest_group": 2, "method": "whole",
}
_TRAJECTORY_EXAMPLE: dict[str, Any] = {
    "id": "uav1", "t": [0.0, 0.2], "position": [[4.5, 2.5, 1.1], [4.4976, 2.5, 1.1]],
    "velocity": [[0.0, 0.0, 0.0], [-0.024, 0.0, 0.0]], "acceleration": [[-0.12, 0.0, 0.0]],
    "jerk": [[-0.6, 0.0, 0.0]], "thrust": [9.8107], "body_rates": [[0.0, -0.061, 0.0]],
}
_PLAN_EXAMPLE: dict[str, Any] = {
    "status": "converged", "message": "cost changed by 0.0396 < 0.05", "solver": "piqp",
    "infeasible_groups": [], "scenario": EXAMPLE_SCENARIO, "iterations": [_ITERATION],
    "timing": {"total_s": 0.21, "first_qp_s": 0.004}, "vehicles": [_TRAJECTORY_EXAMPLE],
    "verification": {"min_separation": 1.0004, "min_separation_continuous": 1.0001,
                     "closest_pair": ["uav1", "uav3"], "closest_time": 14.9,
                     "max_violation": {"position": 0.0}, "boundary_error": {"goal": 1e-9},
                     "thrust_range": [9.2, 10.4], "body_rate_peak": 0.3,
                     "flyable": True, "separated": True, "within_bounds": True,
                     "separation_tolerance": 0.001, "bound_tolerance": 1e-4},
    "sequence": None,
    "horizon": None,
    "method": "whole",
    "attempts": [{"method": "whole", "outcome": "won",
                  "reason": "cost changed by 0.0396 < 0.05", "seconds": 0.2}],
}
_SUMMARY_EXAMPLE: dict[str, Any] = {
    "id": "3f2a9c81d0b4", "name": "paper-circle4", "status": "planned",
    "created_at": "2026-11-23T08:30:00+00:00", "updated_at": "2026-11-23T08:30:01+00:00",
    "vehicle_count": 4, "steps": 150, "dt": 0.2, "horizon_s": 30.0,
    "plan_status": "converged", "plan_ok": True, "error": None,
}

# --------------------------------------------------------------------------- derived schemas

#: The planner's contract types, by component name, and an example of each.
_SCENARIO_TYPES: dict[str, type] = {
    "Scenario": planner_scenario.Scenario,
    "Limits": planner_scenario.Limits,
    "Vehicle": planner_scenario.Vehicle,
    "Obstacle": planner_obstacles.Obstacle,
    "BoxShape": planner_obstacles.BoxShape,
    "CylinderShape": planner_obstacles.CylinderShape,
    "PrismShape": planner_obstacles.PrismShape,
    "FixedTrajectory": planner_fixed.FixedTrajectory,
}
#: The obstacle example: a pillar in the middle of the paper's workspace.
_OBSTACLE_EXAMPLE: dict[str, Any] = {
    "id": "pillar", "cylinder": {"center": [2.5, 2.5], "radius": 0.3, "z": [0.0, 3.0]}}
_PLAN_TYPES: dict[str, type] = {
    "Plan": planner_result.Plan,
    "VehicleTrajectory": planner_result.VehicleTrajectory,
    "IterationRecord": planner_result.IterationRecord,
    "Verification": planner_result.Verification,
    "Attempt": planner_result.Attempt,
}
_EXAMPLES: dict[str, Any] = {
    "Scenario": EXAMPLE_SCENARIO,
    "Limits": EXAMPLE_SCENARIO["limits"],
    "Vehicle": EXAMPLE_SCENARIO["vehicles"][0],
    "Obstacle": _OBSTACLE_EXAMPLE,
    "BoxShape": {"min": [1.0, 1.0, 0.0], "max": [1.5, 2.0, 3.0]},
    "CylinderShape": _OBSTACLE_EXAMPLE["cylinder"],
    "PrismShape": {"polygon": [[1.0, 1.0], [2.0, 1.0], [1.5, 2.0]], "z": [0.0, 3.0]},
    "FixedTrajectory": {"id": "uav9", "positions": [[2.5, 2.5, 1.0], [2.5, 2.5, 0.9]],
                        "margin": 0.5},
    "Plan": _PLAN_EXAMPLE,
    "VehicleTrajectory": _TRAJECTORY_EXAMPLE,
    "IterationRecord": _ITERATION,
    "Verification": _PLAN_EXAMPLE["verification"],
    "Attempt": _PLAN_EXAMPLE["attempts"][0],
}
_COMPONENT_OF = {cls: name for name, cls in {**_SCENARIO_TYPES, **_PLAN_TYPES}.items()}

_VECTOR3: dict[str, Any] = {
    "type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3,
    "description": "[x, y, z], world frame ENU (z up).",
}


def ref(name: str) -> dict[str, str]:
    """An OpenAPI reference to a component schema."""
    return {"$ref": f"#/components/schemas/{name}"}


def _attribute_docs(cls: type) -> dict[str, str]:
    """The docstrings written under a dataclass's fields (the planner documents them there)."""
    tree = ast.parse(inspect.getsource(cls).lstrip())
    body = tree.body[0].body  # type: ignore[attr-defined]
    docs: dict[str, str] = {}
    for field_node, doc_node in itertools.pairwise(body):
        if (isinstance(field_node, ast.AnnAssign) and isinstance(field_node.target, ast.Name)
                and isinstance(doc_node, ast.Expr) and isinstance(doc_node.value, ast.Constant)
                and isinstance(doc_node.value.value, str)):
            docs[field_node.target.id] = " ".join(doc_node.value.value.split())
    return docs


def _is_array(hint: Any) -> bool:
    return typing.get_origin(hint) is np.ndarray


def _array_schema(doc: str) -> dict[str, Any]:
    """A numpy field as JSON: its docstring starts with its shape when it is not a 3-vector,
    e.g. "(K+1, 3) positions" or "(K,) thrust"."""
    shape = re.match(r"\(([^)]*)\)", doc)
    if shape is None:
        return dict(_VECTOR3)
    dims = [d.strip() for d in shape.group(1).split(",") if d.strip()]
    schema: dict[str, Any] = {"type": "number"}
    for dim in reversed(dims):
        schema = {"type": "array", "items": schema}
        if dim.isdigit():
            schema.update(minItems=int(dim), maxItems=int(dim))
    return schema


def _type_schema(hint: Any, doc: str) -> dict[str, Any]:
    if hint is Any:
        return {}
    if _is_array(hint):
        return _array_schema(doc)
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        inner = _type_schema(options[0], doc) if len(options) == 1 else {
            "anyOf": [_type_schema(a, doc) for a in options]}
        return {"anyOf": [inner, {"type": "null"}]} if type(None) in args else inner
    if origin in (tuple, list):
        return {"type": "array", "items": _type_schema(args[0], "") if args else {}}
    if origin in (dict, collections.abc.Mapping):
        return {"type": "object", "additionalProperties": _type_schema(args[1], "")}
    if hint in _COMPONENT_OF:
        return ref(_COMPONENT_OF[hint])
    simple = {str: "string", int: "integer", float: "number", bool: "boolean"}
    if hint in simple:
        return {"type": simple[hint]}
    raise TypeError(f"no JSON schema for {hint!r}")


def _component(name: str, cls: type, *, input_rules: bool) -> dict[str, Any]:
    """One dataclass as an object schema. Fields the planner keeps out of `repr` are derived
    arrays (starts, goals), not JSON fields. With `input_rules`, a field is required unless it
    has a default (`planner.model.scenario.DEFAULTS` or the dataclass's) or may be null."""
    # The scenario names the obstacle and fixed types for type checkers only (no import
    # cycle).
    hints = typing.get_type_hints(cls, localns={**vars(planner_obstacles),
                                                **vars(planner_fixed)})
    docs = _attribute_docs(cls)
    properties: dict[str, Any] = {}
    required: list[str] = []
    for f in dataclasses.fields(cls):
        if not f.repr:
            continue
        doc = docs.get(f.name, "")
        schema = _type_schema(hints[f.name], doc)
        if "$ref" in schema:
            schema = {"allOf": [schema]}  # a $ref with siblings is ignored by some tools
        if doc:
            schema["description"] = doc
        optional = type(None) in typing.get_args(hints[f.name])
        default = planner_scenario.DEFAULTS.get(f.name, f.default)
        if input_rules and default is not dataclasses.MISSING:
            schema["default"] = default
        elif not (input_rules and optional) and "omitted" not in f.metadata:
            required.append(f.name)  # (fields a document may omit say so in their metadata)
        properties[f.name] = schema
    description = " ".join((inspect.getdoc(cls) or "").split())
    component: dict[str, Any] = {
        "title": name, "type": "object", "description": description,
        "properties": properties, "required": required, "examples": [_EXAMPLES[name]],
    }
    # The planner refuses unknown keys in what it reads; what it writes may gain keys that
    # are not dataclass fields (a client should ignore what it does not know).
    if input_rules:
        component["additionalProperties"] = False
    return component


#: Builds the components once: the first requests arrive together, from several threads, and
#: `ast.parse` (the field docs) is not safe to run in parallel in CPython 3.11.
_BUILD_LOCK = threading.Lock()


def planner_schemas() -> dict[str, dict[str, Any]]:
    """OpenAPI components for the scenario (input rules) and the plan (every field present)."""
    with _BUILD_LOCK:
        return _planner_schemas()


@cache
def _planner_schemas() -> dict[str, dict[str, Any]]:
    out = {name: _component(name, cls, input_rules=True) for name, cls in _SCENARIO_TYPES.items()}
    out.update(
        {name: _component(name, cls, input_rules=False) for name, cls in _PLAN_TYPES.items()}
    )
    out["Plan"]["properties"]["status"]["enum"] = list(planner_result.STATUSES)
    steps = out["Scenario"]["properties"]["steps"]
    steps["anyOf"] = [{"type": steps.pop("type")},
                      {"type": "string", "enum": [planner_scenario.AUTO_STEPS]}]
    out["Attempt"]["properties"]["outcome"]["enum"] = list(planner_result.OUTCOMES)
    out["Scenario"]["properties"]["method"]["enum"] = list(planner_scenario.METHODS)
    # Plan.to_dict writes these with every default filled in, so they are always present.
    return out


# --------------------------------------------------------------------------- shape check


def _where(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _json_type(value: Any) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean",
            type(None): "null"}.get(type(value), "number")


def _resolve(schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema or "allOf" in schema:
        schema = schema["allOf"][0] if "allOf" in schema else planner_schemas()[
            schema["$ref"].rsplit("/", 1)[1]]
    return schema


def _check(value: Any, schema: dict[str, Any], path: str, out: list[ErrorItem]) -> None:
    schema = _resolve(schema)
    if "anyOf" in schema:
        options = schema["anyOf"]
        if value is None and {"type": "null"} in options:
            return
        # the option of the value's JSON type (the first, for an error of type)
        typed = [_resolve(o) for o in options if o != {"type": "null"}]
        schema = next((o for o in typed if _json_type(value) == o.get("type")
                       or (o.get("type") == "integer" and _json_type(value) == "number")),
                      typed[0])
    kind = schema.get("type")
    if kind == "object":
        if not isinstance(value, dict):
            out.append(ErrorItem(field=path or "body", reason="must be a JSON object, got "
                                 f"{_json_type(value)}"))
            return
        properties = schema.get("properties", {})
        for key in value:
            if key not in properties:
                out.append(ErrorItem(field=_where(path, key),
                                     reason=unknown_key(key, properties)))
        for key in schema.get("required", ()):
            if key not in value:
                out.append(ErrorItem(field=_where(path, key), reason="is required"))
        for key, sub in properties.items():
            if key in value:
                _check(value[key], sub, _where(path, key), out)
    elif kind == "array":
        size = schema.get("maxItems")
        if not isinstance(value, list) or (size is not None and len(value) != size):
            reason = (f"must be a list of {size} numbers [x, y, z]" if size == 3
                      else f"must be a list of {size} numbers"
                      if size is not None and isinstance(value, list)
                      else f"must be a list, got {_json_type(value)}")
            out.append(ErrorItem(field=path, reason=reason))
            return
        for index, item in enumerate(value):
            _check(item, schema.get("items", {}), _where(path, index), out)
    elif kind in ("number", "integer"):
        if isinstance(value, bool) or not isinstance(value, int | float):
            out.append(ErrorItem(field=path, reason=f"must be a number, got {_json_type(value)}"
                                 if kind == "number" else
                                 f"must be an integer, got {_json_type(value)}"))
        elif kind == "integer" and isinstance(value, float) and not value.is_integer():
            out.append(ErrorItem(field=path, reason=f"must be an integer, got {value}"))
    elif kind == "string" and not isinstance(value, str):
        out.append(ErrorItem(field=path, reason=f"must be a string, got {_json_type(value)}"))


def shape_errors(body: Any, component: Literal["Scenario"] = "Scenario") -> list[ErrorItem]:
    """Every problem of type, key or vector length in a JSON body, by dotted path."""
    out: list[ErrorItem] = []
    _check(body, ref(component), "", out)
    return out


# --------------------------------------------------------------------------- API documents

#: A field holding a planner document, documented by its derived component.
PlanDoc = Annotated[dict[str, Any] | None, WithJsonSchema(
    {"anyOf": [ref("Plan"), {"type": "null"}], "description": "The Plan JSON once planned."})]
ScenarioDoc = Annotated[dict[str, Any], WithJsonSchema(
    {"allOf": [ref("Scenario")], "description": "The scenario, with defaults filled in."})]
ProgressDoc = Annotated[list[dict[str, Any]], WithJsonSchema(
    {"type": "array", "items": ref("IterationRecord"),
     "description": "SCP iterations reported so far while planning (empty otherwise)."})]


class MissionSummary(BaseModel):
    """A mission without its scenario and plan, as listed."""

    model_config = ConfigDict(json_schema_extra={"examples": [_SUMMARY_EXAMPLE]})

    id: str
    name: str
    status: MissionStatus = Field(
        description="planning until the worker answers; planned whatever the plan's status; "
        "failed if there is no plan (see `error`)."
    )
    created_at: str
    updated_at: str
    vehicle_count: int
    steps: int
    dt: float
    horizon_s: float
    plan_status: str | None = Field(description="The plan's own status once planned.")
    plan_ok: bool | None = Field(description="Converged and verified (separated, in bounds).")
    error: ErrorItem | None = Field(description="Why planning failed, if it did.")


class MissionOut(MissionSummary):
    """A mission: its scenario, planning progress and, once planned, its plan."""

    model_config = ConfigDict(json_schema_extra={"examples": [{
        **_SUMMARY_EXAMPLE, "status": "planning", "plan_status": None, "plan_ok": None,
        "progress": [{**_ITERATION, "iteration": 0, "cost_change": None}],
        "planning": {"elapsed_s": 0.4, "iterations": 1,
                     "last": {**_ITERATION, "iteration": 0, "cost_change": None},
                     "working": None, "batches": None},
        "scenario": EXAMPLE_SCENARIO, "plan": None,
        "links": {"self": "/api/missions/3f2a9c81d0b4",
                  "events": "/api/missions/3f2a9c81d0b4/events",
                  "trajectory": "/api/missions/3f2a9c81d0b4/trajectory?rate=20",
                  "show_skyc": "/api/missions/3f2a9c81d0b4/show.skyc",
                  "flights": "/api/missions/3f2a9c81d0b4/flights"},
    }]})

    progress: ProgressDoc
    planning: dict[str, Any] | None = Field(
        default=None, description="While planning: elapsed_s (since a worker began), "
        "iterations (records so far), last (the last record), working (the last report from "
        "inside the iteration under way: iteration, round, groups_done, groups, qp_solves, "
        "seconds, method, batch, batches; null between iterations) and batches ({done, "
        "total, remaining_s}: prioritized batches done and the time left at the mean time "
        "per batch so far, null until one is done; null without batches). Null otherwise.")
    scenario: ScenarioDoc
    plan: PlanDoc
    links: dict[str, str]


class MissionList(BaseModel):
    """A page of missions, newest first."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"total": 1, "limit": 50, "offset": 0, "missions": [_SUMMARY_EXAMPLE]}]})

    total: int
    limit: int
    offset: int
    missions: list[MissionSummary]


class TrajectoryVehicleOut(BaseModel):
    """One vehicle's sampled setpoints."""

    model_config = ConfigDict(json_schema_extra={"examples": [{
        "id": "uav1", "position": [[4.5, 2.5, 1.1]], "velocity": [[0.0, 0.0, 0.0]],
        "acceleration": [[-0.12, 0.0, 0.0]]}]})

    id: str
    position: list[list[float]] = Field(description="(M, 3) positions (m), world frame ENU.")
    velocity: list[list[float]] = Field(description="(M, 3) velocities (m/s).")
    acceleration: list[list[float]] = Field(description="(M, 3) accelerations (m/s^2).")
    lights: list[tuple[float, float, str]] | None = Field(
        default=None, description="A show's light changes, when its plan has a light design: "
        "[start s, end s, \"#rrggbb\"] rows in time order, the light reaching the colour "
        "linearly over [start, end] from what it showed at start (dark before the first).")


class TrajectoryOut(BaseModel):
    """The plan sampled at `rate` Hz with the exact motion between steps (the setpoints)."""

    model_config = ConfigDict(json_schema_extra={"examples": [{
        "mission_id": "3f2a9c81d0b4", "rate": 20.0, "frame": "world_enu", "t": [0.0, 0.05],
        "vehicles": [{"id": "uav1", "position": [[4.5, 2.5, 1.1], [4.4999, 2.5, 1.1]],
                      "velocity": [[0.0, 0.0, 0.0], [-0.003, 0.0, 0.0]],
                      "acceleration": [[-0.12, 0.0, 0.0], [-0.12, 0.0, 0.0]]}]}]})

    mission_id: str
    rate: float
    frame: Literal["world_enu"]
    t: list[float] = Field(description="M sample times (s), 0 to the horizon.")
    vehicles: list[TrajectoryVehicleOut]
