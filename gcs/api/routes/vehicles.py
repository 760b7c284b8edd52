"""/api/vehicles: the configured fleet with every vehicle's live link state; a command to one
vehicle (/api/vehicles/{id}/commands, the body of /api/fleet/commands)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Path
from pydantic import BaseModel, ConfigDict, Field

from gcs.api.deps import FleetDep
from gcs.api.errors import error_responses
from gcs.api.routes.fleet import CommandOut, CommandRequest
from gcs.errors import NotFound

__all__ = ["router"]

router = APIRouter(prefix="/vehicles", tags=["vehicles"])


class VehiclesOut(BaseModel):
    model_config = ConfigDict(json_schema_extra={"examples": [{
        "fleet": {"kind": "mock", "vehicles": 4, "ids": ["uav1", "uav2", "uav3", "uav4"],
                  "flying": None, "vehicle_process": "running", "grows_to": 256,
                  "world_origin": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}},
        "vehicles": [{"id": "uav1", "system_id": 1, "connection": "udpin:127.0.0.1:14540",
                      "link": "monitor", "autopilot": "px4", "heartbeat_age": 0.12,
                      "mode": "AUTO.LOITER",
                      "armed": False, "position": [0.0, -2.0, 0.0], "home": [0.0, -2.0, 0.0]}],
    }]})

    fleet: dict[str, Any] = Field(description="kind (mock, file, none), vehicles, ids, the "
                                  "flight flying now (or null), world_origin {lat, lon, "
                                  "alt} (deg, deg, m AMSL) of the world frame, or null, "
                                  "grows_to (a mock fleet that adds vehicles as a plan needs "
                                  "them: the most it may have; null: the fleet keeps its "
                                  "size), and vehicle_process (running, or stopped while the "
                                  "service restarts it).")
    vehicles: list[dict[str, Any]] = Field(
        description="Per vehicle: id, autopilot (px4 or ardupilot: detected from its "
        "HEARTBEAT or named in the fleet file; null before either), heartbeat_age (s, null "
        "before the first), mode, armed, "
        "position (world frame ENU, m, when the home is known), link (monitor between "
        "flights, flight during one); battery {remaining_pct, voltage}, gps {fix_type, "
        "satellites, h_acc, v_acc (m)}, health {unhealthy (sensor names), prearm_ok, "
        "warnings}, link_quality {received, lost, loss_pct} (null = not reported)."
    )


@router.get("", response_model=VehiclesOut, summary="The fleet and its live link state")
async def list_vehicles(fleet: FleetDep) -> dict[str, Any]:
    return {"fleet": fleet.describe(), "vehicles": await fleet.vehicles()}


@router.post(
    "/{vehicle_id}/commands",
    response_model=CommandOut,
    summary="Command one vehicle between flights (hold, land, rtl, disarm, terminate)",
    responses=error_responses(400, 404, 409, 413, 422),
)
async def vehicle_commands(
    fleet: FleetDep,
    vehicle_id: Annotated[str, Path(description="Vehicle id.", max_length=64)],
    request: Annotated[CommandRequest, Body()],
) -> dict[str, Any]:
    """As POST /api/fleet/commands, for this vehicle only."""
    if vehicle_id not in fleet.describe()["ids"]:
        raise NotFound("vehicle_id", f"no vehicle {vehicle_id!r} in the fleet")
    return await fleet.command(request.command, [vehicle_id], force=request.force,
                               confirm=request.confirm)
