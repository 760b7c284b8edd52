"""Request and response models of the REST API (pydantic), with examples for the OpenAPI page.

The scenario model checks the JSON's shape (types, 3-vectors, no unknown keys); everything
that needs the numbers themselves (workspace, separation, reachable goals) is checked by
`planner.Scenario.from_dict`, the single definition of a valid scenario. Response models
document the Plan JSON contract of `planner.Plan.to_dict`; the API sends the stored plan text
as it is rather than re-validating it on every request.
"""

from __future__ import annotations

import json
from importlib import resources
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from gcs.api.errors import ErrorItem
from gcs.service.store import MISSION_STATUSES
from planner.result import STATUSES

__all__ = [
    "EXAMPLE_SCENARIO",
    "IterationOut",
    "LimitsIn",
    "MissionList",
    "MissionOut",
    "MissionSummary",
    "PlanOut",
    "ScenarioIn",
    "TrajectoryOut",
    "VehicleIn",
    "VehicleTrajectoryOut",
]

Vector3 = Annotated[list[float], Field(min_length=3, max_length=3, examples=[[0.5, 2.5, 1.1]])]


def _example_scenario() -> dict[str, Any]:
    text = resources.files("planner").joinpath("examples/paper-circle4.json").read_text()
    return json.loads(text)


#: The paper's 4-vehicle circle case, shown as the request example.
EXAMPLE_SCENARIO: dict[str, Any] = _example_scenario()


_ITERATION: dict[str, Any] = {
    "iteration": 1, "cost": 14433.1, "cost_change": 0.115, "separation_rows": 96,
    "qp_solves": 1, "groups": 2, "seconds": 0.02,
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
                     "flyable": True, "separated": True, "within_bounds": True},
}
_SUMMARY_EXAMPLE: dict[str, Any] = {
    "id": "3f2a9c81d0b4", "name": "paper-circle4", "status": "planned",
    "created_at": "2026-11-23T08:30:00+00:00", "updated_at": "2026-11-23T08:30:01+00:00",
    "vehicle_count": 4, "steps": 150, "dt": 0.2, "horizon_s": 30.0,
    "plan_status": "converged", "plan_ok": True, "error": None,
}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class LimitsIn(_Strict):
    """Workspace box and per-axis symmetric bounds (m, m/s, m/s^2, m/s^3; rad/s)."""

    model_config = ConfigDict(
        extra="forbid", strict=True,
        json_schema_extra={"examples": [EXAMPLE_SCENARIO["limits"]]},
    )


    position_min: Vector3 = Field(description="Lower corner of the workspace box (m).")
    position_max: Vector3 = Field(description="Upper corner of the workspace box (m).")
    velocity_max: Vector3 | None = Field(None, description="Per-axis |v| bound; null: none.")
    acceleration_max: Vector3 | None = Field(None, description="Per-axis |a| bound; null: none.")
    jerk_max: Vector3 | None = Field(None, description="Per-axis |jerk| bound; null: none.")
    thrust_min: float | None = Field(None, description="Lowest mass-normalised thrust (m/s^2).")
    thrust_max: float | None = Field(None, description="Highest mass-normalised thrust (m/s^2).")
    body_rate_max: float | None = Field(None, description="Highest roll/pitch rate (rad/s).")


class VehicleIn(_Strict):
    """One vehicle's task: from `start` to `goal`, both at rest, world frame ENU (z up)."""

    model_config = ConfigDict(
        extra="forbid", strict=True,
        json_schema_extra={"examples": [EXAMPLE_SCENARIO["vehicles"][0]]},
    )


    id: str = Field(description="Unique vehicle id; matches the fleet file's ids.")
    start: Vector3
    goal: Vector3


class ScenarioIn(_Strict):
    """A planning problem (the scenario JSON contract). Unknown keys are errors."""

    model_config = ConfigDict(
        extra="forbid", strict=True, json_schema_extra={"examples": [EXAMPLE_SCENARIO]}
    )

    name: str | None = Field(None, description="Free-form name (default 'scenario').")
    dt: float = Field(description="Step length (s).")
    steps: int = Field(description="Number of steps K; the horizon is K * dt.")
    min_separation: float = Field(description="R (m): minimum distance between any two vehicles.")
    separation_scale: Vector3 | None = Field(
        None, description="Per-axis scale of the separation metric ([1, 1, 2]: downwash)."
    )
    cost_threshold: float | None = Field(None, description="SCP convergence threshold.")
    max_iterations: int | None = Field(None, description="Cap on SCP iterations.")
    limits: LimitsIn
    vehicles: list[VehicleIn] = Field(description="The fleet's tasks, at least one.")

    def to_contract(self) -> dict[str, Any]:
        """The scenario JSON for `planner.Scenario.from_dict` (omitted values left out)."""
        return self.model_dump(exclude_none=True)


class IterationOut(BaseModel):
    """One SCP iteration (iteration 0 is the separation-free first QP)."""

    model_config = ConfigDict(json_schema_extra={"examples": [_ITERATION]})


    iteration: int
    cost: float
    cost_change: float | None
    separation_rows: int
    qp_solves: int
    groups: int
    seconds: float
    largest_group: int = 0


class VehicleTrajectoryOut(BaseModel):
    """One vehicle's planned motion on the step grid (world frame ENU, SI units)."""

    model_config = ConfigDict(json_schema_extra={"examples": [_TRAJECTORY_EXAMPLE]})


    id: str
    t: list[float] = Field(description="K+1 step times (s).")
    position: list[list[float]] = Field(description="K+1 positions (m).")
    velocity: list[list[float]] = Field(description="K+1 velocities (m/s).")
    acceleration: list[list[float]] = Field(description="K accelerations (m/s^2).")
    jerk: list[list[float]] = Field(description="K jerks (m/s^3).")
    thrust: list[float] = Field(description="K mass-normalised thrusts (m/s^2).")
    body_rates: list[list[float]] = Field(description="K body rates (rad/s).")


class PlanOut(BaseModel):
    """The Plan JSON contract (`planner.Plan.to_dict`)."""

    model_config = ConfigDict(json_schema_extra={"examples": [_PLAN_EXAMPLE]})


    status: Literal[STATUSES] = Field(  # type: ignore[valid-type]
        description="The planner's verdict."
    )
    message: str
    solver: str
    infeasible_groups: list[str]
    scenario: dict[str, Any] = Field(description="The scenario, with defaults filled in.")
    iterations: list[IterationOut]
    timing: dict[str, float | None] = Field(description="total_s, first_qp_s, ...")
    vehicles: list[VehicleTrajectoryOut]
    verification: dict[str, Any] | None = Field(
        description="min_separation, min_separation_continuous, closest_pair, max_violation, "
        "boundary_error, thrust_range, body_rate_peak, flyable, separated, within_bounds, ..."
    )


class MissionSummary(BaseModel):
    """A mission without its scenario and plan, as listed."""

    model_config = ConfigDict(json_schema_extra={"examples": [_SUMMARY_EXAMPLE]})


    id: str
    name: str
    status: Literal[MISSION_STATUSES] = Field(  # type: ignore[valid-type]
        description="planning until the worker answers; planned whatever the plan's status; "
        "failed if the planner raised (see `error`)."
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

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": "3f2a9c81d0b4",
                    "name": "paper-circle4",
                    "status": "planning",
                    "created_at": "2026-11-23T08:30:00+00:00",
                    "updated_at": "2026-11-23T08:30:00+00:00",
                    "vehicle_count": 4,
                    "steps": 150,
                    "dt": 0.2,
                    "horizon_s": 30.0,
                    "plan_status": None,
                    "plan_ok": None,
                    "error": None,
                    "progress": [
                        {"iteration": 0, "cost": 14433.1, "cost_change": None,
                         "separation_rows": 0, "qp_solves": 1, "groups": 4, "seconds": 0.02}
                    ],
                    "scenario": EXAMPLE_SCENARIO,
                    "plan": None,
                    "links": {
                        "self": "/api/missions/3f2a9c81d0b4",
                        "events": "/api/missions/3f2a9c81d0b4/events",
                        "trajectory": "/api/missions/3f2a9c81d0b4/trajectory?rate=20",
                        "executions": "/api/missions/3f2a9c81d0b4/executions",
                    },
                }
            ]
        }
    )

    progress: list[IterationOut] = Field(
        description="SCP iterations reported so far while planning (empty otherwise)."
    )
    scenario: dict[str, Any] = Field(description="The scenario, with defaults filled in.")
    plan: PlanOut | None = Field(description="The Plan JSON once planned, else null.")
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
