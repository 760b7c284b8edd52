"""An operator's in-flight replan request: its body and its checks, one definition for the
REST route (POST /api/flights/{id}/replan) and `fleetplan fly`'s control socket.

The body names new goals, vehicles to drop, or both. What only the flight can judge (the
vehicle ids, each goal against the workspace, the obstacles and the other goals) is checked
by `FlightExecutor.replan`; here the shape is: finite 3-vectors, bounded ids and counts, and
(`check_entries`, which the flight applies to every request too) a known drop action, no
vehicle listed twice or both dropped and given a goal.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from gcs.errors import InvalidRequest, field_path
from gcs.phases import DROP_ACTIONS, DropAction

__all__ = ["DROP_ACTIONS", "MAX_ENTRIES", "SERVICE_LIMIT", "DropAction", "GoalPoint",
           "ReplanRequest", "VehicleId", "check_entries", "checked", "parse"]

#: Most vehicles one replan names in `goals`, and in `drop`: a replan of more could not be
#: planned within any lead (100 vehicles take about 2 s), and the body stays small.
MAX_ENTRIES = 512
#: A vehicle id in a replan (as long as a fleet command's).
VehicleId = Annotated[str, Field(min_length=1, max_length=64)]
#: A new goal: x, y, z in the world frame (ENU, m), finite.
GoalPoint = Annotated[list[Annotated[float, Field(allow_inf_nan=False)]],
                      Field(min_length=3, max_length=3)]


class ReplanRequest(BaseModel):
    """An in-flight replan: new goals for some vehicles, some vehicles dropped. `goals`,
    `drop` or both; a vehicle is either given a goal or dropped."""

    model_config = ConfigDict(
        extra="forbid", strict=True,
        json_schema_extra={"examples": [
            {"goals": {"uav2": [4.0, 1.5, 2.0]}},
            {"drop": ["uav3"], "drop_action": "land"},
            {"goals": {"uav1": [1.0, 4.0, 2.5]}, "drop": ["uav3"], "drop_action": "hold"}]},
    )

    goals: dict[VehicleId, GoalPoint] | None = Field(
        None, max_length=MAX_ENTRIES,
        description="Vehicle id -> its new goal [x, y, z] (world frame ENU, m): inside the "
        "workspace, clear of the obstacles, at least R from every other goal. The vehicles "
        "not named keep their goals.")
    drop: list[VehicleId] | None = Field(
        None, max_length=MAX_ENTRIES,
        description="Vehicles that leave the plan: each lands (or holds) on its own motion, "
        "which the others' new plan keeps R from.")
    drop_action: DropAction = Field(
        "land", description="What a dropped vehicle does: land, or brake and hold where it "
        "stops.")


#: How `checked` names the bound on entries by default (the service's setting).
SERVICE_LIMIT = "this server's fleet limit of {max} (setting max_vehicles)"


def checked(request: ReplanRequest, max_vehicles: int, limit: str = SERVICE_LIMIT
            ) -> tuple[dict[str, list[float]] | None, list[str]]:
    """The request's goals (None: unchanged) and drop list, checked against each other and
    against `max_vehicles` entries (`limit` names that bound, {max} its value);
    InvalidRequest naming the field otherwise."""
    goals, drop = request.goals, list(request.drop or ())
    if not goals and not drop:
        raise InvalidRequest("goals", "give new goals, vehicles to drop, or both")
    for name, count in (("goals", len(goals or ())), ("drop", len(drop))):
        if count > max_vehicles:
            raise InvalidRequest(name, f"{count} entries exceed "
                                       f"{limit.format(max=max_vehicles)}")
    check_entries(goals, drop, request.drop_action)
    return (dict(goals) if goals else None), drop


def check_entries(goals: Mapping[str, Any] | None, drop: Sequence[str], drop_action: str
                  ) -> DropAction:
    """A replan's entries against each other: `drop_action` one of `DROP_ACTIONS`, `drop` a
    list naming each vehicle once, `goals` an object, no vehicle both dropped and given a
    goal; InvalidRequest naming the field otherwise. Returns the drop action as checked."""
    action = next((a for a in DROP_ACTIONS if a == drop_action), None)
    if action is None:
        raise InvalidRequest("drop_action", f"must be one of {', '.join(DROP_ACTIONS)}, "
                                            f"got {drop_action!r}")
    if isinstance(drop, str):
        raise InvalidRequest("drop", "must be a list of vehicle ids")
    if goals is not None and not isinstance(goals, Mapping):
        raise InvalidRequest("goals", "must be an object {vehicle id: [x, y, z]}")
    seen: set[str] = set()
    for n, vehicle in enumerate(drop):
        if not isinstance(vehicle, str):
            raise InvalidRequest(f"drop[{n}]", f"must be a vehicle id, got {vehicle!r}")
        if vehicle in seen:
            raise InvalidRequest(f"drop[{n}]", f"{vehicle!r} is listed twice")
        if goals and vehicle in goals:
            raise InvalidRequest(f"goals.{vehicle}", f"{vehicle!r} is dropped: it cannot be "
                                                     "given a goal too")
        seen.add(vehicle)
    return action


def parse(document: Any, max_vehicles: int, limit: str = SERVICE_LIMIT) -> ReplanRequest:
    """A decoded JSON document as a checked `ReplanRequest` (for callers without FastAPI's
    validation); InvalidRequest naming the first offending field otherwise."""
    try:
        request = ReplanRequest.model_validate(document)
    except ValidationError as exc:
        first = exc.errors()[0]
        raise InvalidRequest(field_path(first["loc"]) or "body", first["msg"]) from None
    checked(request, max_vehicles, limit)
    return request
