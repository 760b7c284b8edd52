"""/api/vehicles: the configured fleet with every vehicle's live link state."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from pydantic import BaseModel, ConfigDict, Field

from gcs.api.deps import FleetDep

__all__ = ["router"]

router = APIRouter(prefix="/vehicles", tags=["vehicles"])


class VehiclesOut(BaseModel):
    model_config = ConfigDict(json_schema_extra={"examples": [{
        "fleet": {"kind": "mock", "vehicles": 4, "ids": ["uav1", "uav2", "uav3", "uav4"],
                  "flying": None},
        "vehicles": [{"id": "uav1", "system_id": 1, "connection": "udpin:127.0.0.1:14540",
                      "link": "monitor", "heartbeat_age": 0.12, "mode": "AUTO.LOITER",
                      "armed": False, "position": [0.0, -2.0, 0.0], "home": [0.0, -2.0, 0.0]}],
    }]})

    fleet: dict[str, Any] = Field(description="kind (mock, file, none), vehicles, ids, and "
                                  "the execution flying now (or null).")
    vehicles: list[dict[str, Any]] = Field(
        description="Per vehicle: id, heartbeat_age (s, null before the first), mode, armed, "
        "position (world frame ENU, m, when the home is known), link (monitor between "
        "flights, flight during one)."
    )


@router.get("", response_model=VehiclesOut, summary="The fleet and its live link state")
def list_vehicles(fleet: FleetDep) -> dict[str, Any]:
    return {"fleet": fleet.describe(), "vehicles": fleet.vehicles()}
