"""/api/status: is the service up, what are its limits, what is it doing, and the vocabulary
(statuses, phases, event kinds) clients read instead of keeping a copy."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from pydantic import BaseModel, ConfigDict, Field

from gcs.api.deps import PlanningDep, SettingsDep
from gcs.phases import vocabulary
from gcs.service.limits import FIXED_LIMITS, LIMIT_NAMES, limits_in_force
from gcs.service.settings import Settings
from gcs.service.statuses import status_sets

__all__ = ["StatusOut", "router", "status_example"]

router = APIRouter(prefix="/status", tags=["status"])


def status_example() -> dict[str, Any]:
    """An example answer made from the definitions themselves (status sets, vocabulary, the
    settings' defaults), so it always lists what the service really serves."""
    defaults = Settings.model_construct()  # the defaults, no environment or config file
    return {
        "status": "ok", "version": "0.1.0", "planning_jobs": 0,
        "plan_workers": defaults.plan_workers,
        "fleet": {"kind": "mock", "vehicles": 4, "ids": ["uav1", "uav2", "uav3", "uav4"],
                  "flying": None, "world_origin": None,
                  "grows_to": defaults.mock_max_vehicles, "vehicle_process": "running"},
        "limits": limits_in_force(defaults),
        "statuses": status_sets(),
        "phases": vocabulary(),
    }


class StatusOut(BaseModel):
    """Service health and the limits a client should respect."""

    model_config = ConfigDict(json_schema_extra={"examples": [status_example()]})

    status: str = Field(examples=["ok"], description="ok; degraded while the vehicle "
                        "process is not running (the fleet cannot be reached; the service "
                        "restarts it)")
    version: str
    planning_jobs: int = Field(description="Plans computing now.")
    plan_workers: int
    fleet: dict[str, Any] = Field(
        description="kind (mock, file or none), vehicles, ids, flying (flight id or null), "
        "world_origin, grows_to (a mock fleet that adds vehicles as a plan needs them: the "
        "most it may have, setting mock_max_vehicles; null: the fleet keeps its size), "
        "vehicle_process (running or stopped)."
    )
    limits: dict[str, int | float] = Field(
        description="Every limit a request is checked against: "
        f"{', '.join(LIMIT_NAMES)} (the settings of the same names), and "
        f"{', '.join(FIXED_LIMITS)} (fixed)."
    )
    statuses: dict[str, dict[str, list[str]]] = Field(
        description="Every status set, defined once in the service: mission.all, "
        "flight.all / .active (the vehicles may be flying) / .finished (also under execution, "
        "the former name), plan.all (the planner's). Clients read these rather than keeping "
        "a copy."
    )
    phases: dict[str, list[str]] = Field(
        description="The flight's vocabulary, defined once (`gcs.phases`): flight "
        "(phases of a whole flight), vehicle (phases of one vehicle), airborne (the vehicle "
        "phases in the air), event_kinds (the `kind` of each flight event)."
    )


@router.get("", response_model=StatusOut, summary="Service status and limits")
def get_status(request: Request, settings: SettingsDep, planning: PlanningDep) -> dict[str, Any]:
    """Always answers quickly; use it as a health check."""
    fleet = getattr(request.app.state, "fleet", None)
    described = fleet.describe() if fleet is not None else {"kind": "none", "vehicles": 0}
    return {
        "status": "degraded" if described.get("vehicle_process") == "stopped" else "ok",
        "version": request.app.version,
        "planning_jobs": planning.active,
        "plan_workers": settings.plan_workers,
        "fleet": described,
        "limits": limits_in_force(settings),
        "statuses": status_sets(),
        "phases": vocabulary(),
    }
