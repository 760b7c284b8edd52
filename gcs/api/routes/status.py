"""/api/status: is the service up, what are its limits, what is it doing."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from pydantic import BaseModel, Field

from gcs.api.deps import PlanningDep, SettingsDep
from gcs.service.statuses import status_sets

__all__ = ["StatusOut", "router"]

router = APIRouter(prefix="/status", tags=["status"])


class StatusOut(BaseModel):
    """Service health and the limits a client should respect."""

    model_config = {"json_schema_extra": {"examples": [{
        "status": "ok", "version": "0.1.0", "planning_jobs": 0, "plan_workers": 1,
        "fleet": {"kind": "mock", "vehicles": 4, "ids": ["uav1", "uav2", "uav3", "uav4"],
                  "flying": None},
        "limits": {"max_vehicles": 128, "max_steps": 1000, "max_body_bytes": 2000000,
                   "max_trajectory_rate": 100.0},
        "statuses": {
            "mission": {"all": ["planning", "planned", "failed"]},
            "execution": {"all": ["starting", "running", "aborting", "completed", "incomplete",
                                  "aborted", "failed", "interrupted"],
                          "active": ["starting", "running", "aborting"],
                          "finished": ["completed", "incomplete", "aborted", "failed",
                                       "interrupted"]},
            "plan": {"all": ["converged", "max_iterations", "infeasible", "unverified"]}}}]}}

    status: str = Field(examples=["ok"])
    version: str
    planning_jobs: int = Field(description="Plans computing now.")
    plan_workers: int
    fleet: dict[str, Any] = Field(
        description="kind (mock, file or none), vehicles, ids, flying (execution id or null)."
    )
    limits: dict[str, int | float] = Field(
        description="max_vehicles, max_steps, max_body_bytes, max_trajectory_rate."
    )
    statuses: dict[str, dict[str, list[str]]] = Field(
        description="Every status set, defined once in the service: mission.all, "
        "execution.all / .active (the vehicles may be flying) / .finished, plan.all (the "
        "planner's). Clients read these rather than keeping a copy."
    )


@router.get("", response_model=StatusOut, summary="Service status and limits")
def get_status(request: Request, settings: SettingsDep, planning: PlanningDep) -> dict[str, Any]:
    """Always answers quickly; use it as a health check."""
    fleet = getattr(request.app.state, "fleet", None)
    return {
        "status": "ok",
        "version": request.app.version,
        "planning_jobs": planning.active,
        "plan_workers": settings.plan_workers,
        "fleet": fleet.describe() if fleet is not None else {"kind": "none", "vehicles": 0},
        "limits": {
            "max_vehicles": settings.max_vehicles,
            "max_steps": settings.max_steps,
            "max_body_bytes": settings.max_body_bytes,
            "max_trajectory_rate": settings.max_trajectory_rate,
        },
        "statuses": status_sets(),
    }
