"""The GCS's exceptions, one tree rooted in `GcsError`.

- `GcsError`: base class of everything `gcs` raises on purpose.
  - `FleetFileError`: a fleet file (or flight options) is invalid; `field` names the dotted path
    of the offending field and `reason` says why. Also a `planner.errors.FieldError`.
  - `LinkError`: a MAVLink connection could not be opened or used (bad URL, port in use).
  - `VehicleTimeout`: a vehicle did not do something in time (first HEARTBEAT, reaching its
    start, confirming a mode in its HEARTBEAT). Carries `vehicle`.
  - `CommandError`: a command was refused or never acknowledged. Carries `vehicle`, `command`
    (MAV_CMD number) and `result` (MAV_RESULT, or None when no ACK came).
    - `ArmingRefused`: MAV_CMD_COMPONENT_ARM_DISARM was refused for good (DENIED, FAILED, or
      still TEMPORARILY_REJECTED when the arming timeout ran out).
    - `ModeRefused`: MAV_CMD_DO_SET_MODE was refused.
  - `PreflightFailed`: the pre-flight gate found a vehicle unfit to fly (battery, unhealthy
    sensors, link loss, missing); carries `vehicle` and `problems`.
  - `GeofenceFailed`: a vehicle's geofence could not be uploaded, or read back different
    (`gcs.flight.procedure.fence_upload`), or no origin places it; carries `vehicle`.
  - `PlanRejected`: the plan may not be flown (not converged, or its verification failed).
  - `ExportError` (also a `FieldError`): a plan cannot be written in the asked format (a step
    the format cannot time), or an export option is invalid; `field` names which.
  - `FlightAborted`: the flight stopped before completing (abort(),
    a fault policy, Ctrl-C); `reason` says why. The vehicles were sent to hold or land
    before this is raised.
  - `RequestError` (also a `FieldError`): the service cannot carry out a request; `field` names
    what is wrong. `gcs.api.errors` maps each subclass to one HTTP status, in one place.
    - `NotFound`: no such mission, flight, example or vehicle.
    - `StateConflict`: the resource is in the wrong state (still planning, already flying).
    - `InvalidRequest`: the request is well-formed but invalid, or exceeds a server limit.
    - `ServiceBusy`: the service cannot take the work now (a full queue); retry later.
  - `VehicleLoopStopped`: the vehicle thread or process that runs flights is not running
    (never started, stopped, or ended); `gcs.api.errors` maps it to 503.

`field_path` writes a validation error's location (pydantic's) as such a dotted path;
`vehicle_at` finds the id of the vehicle such a path points into.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from planner.errors import FieldError

__all__ = [
    "ArmingRefused",
    "CommandError",
    "ExportError",
    "FailsafeNotSet",
    "FleetFileError",
    "FlightAborted",
    "GcsError",
    "GeofenceFailed",
    "InvalidRequest",
    "LinkError",
    "ModeRefused",
    "NotFound",
    "PlanRejected",
    "PreflightFailed",
    "RequestError",
    "ServiceBusy",
    "StateConflict",
    "VehicleLoopStopped",
    "VehicleTimeout",
    "field_path",
    "vehicle_at",
]


def field_path(loc: Sequence[Any]) -> str:
    """A location (pydantic's ``("vehicles", 2, "goal")``) as the dotted path the errors
    name: ``vehicles[2].goal``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


#: A dotted path into a document's vehicle list: ``vehicles[2]`` or ``vehicles[2].goal``.
_VEHICLE_PATH = re.compile(r"vehicles\[(\d+)\](?:$|[.\[])")


def vehicle_at(field: str | None, document: Any) -> str | None:
    """The id of the vehicle a field path such as ``vehicles[2].goal`` points into, read from
    the scenario or plan `document` it was found in; None when the path names no vehicle or
    that vehicle has no usable id. Errors name the vehicle by id beside its index path."""
    match = _VEHICLE_PATH.match(field or "")
    if match is None or not isinstance(document, dict):
        return None
    vehicles = document.get("vehicles")
    index = int(match.group(1))
    if not isinstance(vehicles, list) or index >= len(vehicles):
        return None
    vehicle = vehicles[index]
    vid = vehicle.get("id") if isinstance(vehicle, dict) else None
    return vid if isinstance(vid, str) and vid else None


class GcsError(Exception):
    """Base class of the GCS's errors."""

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled with its attributes, whatever its constructor takes: errors raised in the
        flight's process reach the service as they were raised
        (`gcs.flight.host.vehicle_process`)."""
        return (_rebuild, (type(self), self.args, self.__dict__))


def _rebuild(cls: type[GcsError], args: tuple[Any, ...], state: dict[str, Any]) -> GcsError:
    """A pickled `GcsError` as it was (its constructor is not called again)."""
    error = cls.__new__(cls)
    error.args = args
    error.__dict__.update(state)
    return error


class FleetFileError(GcsError, FieldError):
    """Bad fleet file or options: `field` is the dotted path, `reason` says why."""


class LinkError(GcsError):
    """A MAVLink connection could not be opened or used."""


class VehicleTimeout(GcsError):
    """A vehicle did not reach an expected state in time."""

    def __init__(self, vehicle: str, what: str) -> None:
        super().__init__(f"{vehicle}: {what}")
        self.vehicle = vehicle
        self.what = what


class CommandError(GcsError):
    """A MAVLink command was refused (`result` is the MAV_RESULT) or never acknowledged."""

    def __init__(self, vehicle: str, command: int, result: int | None, detail: str) -> None:
        super().__init__(f"{vehicle}: {detail}")
        self.vehicle = vehicle
        self.command = command
        self.result = result
        self.detail = detail


class PreflightFailed(GcsError):
    """The pre-flight gate refused a vehicle (`problems` say why)."""

    def __init__(self, vehicle: str, problems: list[str]) -> None:
        super().__init__(f"{vehicle}: pre-flight check failed: {'; '.join(problems)}")
        self.vehicle = vehicle
        self.problems = problems


class GeofenceFailed(GcsError):
    """A vehicle's geofence was not uploaded as built: the flight is refused before arming."""

    def __init__(self, vehicle: str, detail: str) -> None:
        super().__init__(f"{vehicle}: geofence: {detail}")
        self.vehicle = vehicle
        self.detail = detail


class FailsafeNotSet(GcsError):
    """A vehicle's link-loss failsafe parameter could not be read or set before arming: what
    it would do without the station is not known, so the flight is refused."""

    def __init__(self, vehicle: str, parameter: str, detail: str) -> None:
        super().__init__(f"{vehicle}: failsafe: {detail}")
        self.vehicle = vehicle
        self.parameter = parameter
        self.detail = detail


class ArmingRefused(CommandError):
    """Arming was refused for good."""


class ModeRefused(CommandError):
    """A mode change was refused."""


class PlanRejected(GcsError):
    """The plan may not be flown."""


class ExportError(GcsError, FieldError):
    """A plan cannot be exported as asked: `field` names the plan field or export option."""


class FlightAborted(GcsError):
    """The flight stopped before completing; the vehicles were sent to hold or land."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class RequestError(GcsError, FieldError):
    """A request the service cannot carry out: `field` names what is wrong, `reason` why."""


class NotFound(RequestError):
    """No such resource (mission, flight, example, vehicle)."""


class StateConflict(RequestError):
    """The resource is in the wrong state for the request (still planning, already flying)."""


class InvalidRequest(RequestError):
    """Well-formed but invalid, or beyond a server limit."""


class ServiceBusy(RequestError):
    """The service cannot take this work now (a full queue, every export or stream slot
    held): retry later, after about `retry_after_s` (the answer's Retry-After)."""

    def __init__(self, field: str, reason: str, retry_after_s: float = 5.0) -> None:
        super().__init__(field, reason)
        self.retry_after_s = retry_after_s


class VehicleLoopStopped(GcsError):
    """The vehicle loop is not running (never started, stopped, or its thread ended)."""
