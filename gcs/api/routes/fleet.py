"""/api/fleet/commands: hold, land, return to launch, disarm or terminate vehicles between flights.

The same body for one vehicle at /api/vehicles/{id}/commands (`gcs.api.routes.vehicles`).
Each command is acknowledged by the vehicle and its effect confirmed from its HEARTBEAT before
the vehicle counts as done (`gcs.fleet.commands`): a fleet left hovering can always be landed.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body
from pydantic import BaseModel, ConfigDict, Field

from gcs.api.deps import FleetDep
from gcs.api.errors import error_responses
from gcs.phases import FleetCommand

__all__ = ["COMMAND_INFO", "CommandOut", "CommandRequest", "router"]

router = APIRouter(prefix="/fleet", tags=["fleet"])


class CommandRequest(BaseModel):
    """A fleet command. Only `command` is required."""

    model_config = ConfigDict(
        extra="forbid", strict=True,
        json_schema_extra={"examples": [{"command": "land"},
                                        {"command": "hold", "vehicles": ["uav1", "uav3"]},
                                        {"command": "terminate", "confirm": True}]},
    )

    command: FleetCommand = Field(
        description="hold: PX4 Hold where it is; land: land where it is; rtl: return to "
        "launch and land; disarm: stop the motors (refused in the air unless `force`); "
        "terminate: flight termination, motors off at once (needs `confirm`)."
    )
    vehicles: list[Annotated[str, Field(max_length=64)]] | None = Field(
        None, min_length=1, max_length=256,
        description="Vehicle ids, at most 256 (default, or omitted: the whole fleet). "
        "Ignored on /api/vehicles/{id}/commands.",
    )
    force: bool = Field(False, description="disarm only: disarm even in the air (it falls).")
    confirm: bool = Field(False, description="terminate only: must be true.")


class VehicleOutcome(BaseModel):
    vehicle: str
    command: str
    done: bool = Field(description="Acknowledged and its effect seen in telemetry.")
    detail: str
    mode: str | None = Field(description="Mode in the vehicle's HEARTBEAT afterwards.")
    armed: bool | None


class CommandOut(BaseModel):
    """What every vehicle did."""

    model_config = ConfigDict(json_schema_extra={"examples": [{
        "command": "land", "done": True,
        "vehicles": [{"vehicle": "uav1", "command": "land", "done": True,
                      "detail": "landing (AUTO.LAND confirmed)", "mode": "AUTO.LAND",
                      "armed": True}],
    }]})

    command: str
    done: bool = Field(description="Every vehicle done.")
    vehicles: list[VehicleOutcome]


class CommandInfo(BaseModel):
    command: FleetCommand
    description: str
    needs: str | None = Field(description="The body field it needs (force, confirm), if any.")


#: What each command does, for clients building their buttons (GET /api/fleet/commands).
COMMAND_INFO = [
    CommandInfo(command="hold", description="Hold where it is (PX4 Hold, ArduCopter BRAKE).",
                needs=None),
    CommandInfo(command="land", description="Land where it is (NAV_LAND).", needs=None),
    CommandInfo(command="rtl", description="Return to launch (AUTO.RTL) and land.",
                needs=None),
    CommandInfo(command="disarm", description="Stop the motors; refused in the air unless "
                "forced (the vehicle falls).", needs="force (in the air)"),
    CommandInfo(command="terminate", description="Flight termination: motors off at once, "
                "the vehicle falls; until it is restarted.", needs="confirm"),
]


@router.get("/commands", response_model=list[CommandInfo],
            summary="The fleet commands and what each does")
def list_commands() -> list[CommandInfo]:
    return COMMAND_INFO


@router.post(
    "/commands",
    response_model=CommandOut,
    summary="Command the fleet between flights (hold, land, rtl, disarm, terminate)",
    responses=error_responses(400, 409, 413, 422),
)
async def fleet_commands(
    fleet: FleetDep, request: Annotated[CommandRequest, Body()]
) -> dict[str, Any]:
    """Sent to every chosen vehicle at once; answers when each confirmed it (or after about
    5 s without confirmation: `done` false, `detail` says why). 409 while a flight is under way
    (use its abort or pause), or for a disarm in the air without `force`; 422 for a terminate
    without `confirm` or an unknown vehicle."""
    return await fleet.command(request.command, request.vehicles, force=request.force,
                               confirm=request.confirm)
