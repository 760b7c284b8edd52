"""The JSON documents a flight hands out, typed once: its events, its live snapshot and its
replan objects.

They are TypedDicts (plain dicts at run time), so the record, the REST API, the page and
``fleetplan fly`` read the same keys the flight writes, and mypy checks both ends. Their
words are `gcs.phases`' enums and Literals (StrEnums: the JSON carries the plain value).
Times are seconds (events on the GCS clock, the rest in flight time), positions in the world
frame (ENU, m); None is unknown. `current_events` reads stored events back as `FlightEvent`s.

The REST API's schema of them is derived from these classes, their attribute docstrings as
the field descriptions; pydantic takes a TypedDict only from ``typing_extensions`` on Python
3.11.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any, NotRequired

from pydantic import ConfigDict, with_config
from typing_extensions import TypedDict

from gcs.phases import DropAction, EventKind, FlightPhase, ReplanStatus, VehiclePhase

__all__ = [
    "BatteryReport",
    "FlightEvent",
    "FlightSnapshot",
    "GpsReport",
    "HealthReport",
    "LinkQualityReport",
    "ReplanDocument",
    "SensorReport",
    "VehicleSnapshot",
    "current_events",
    "finite_or_none",
]

#: The field docstrings are the API schema's field descriptions.
_DOCUMENTED = with_config(ConfigDict(use_attribute_docstrings=True))


@_DOCUMENTED
class FlightEvent(TypedDict):
    """One line of a flight's event log."""

    t: float
    vehicle: str | None
    """The vehicle it is about; None for the fleet."""
    kind: EventKind | str
    """An `EventKind`; a stored kind this version does not know (a record written by another
    version) is kept as it was stored."""
    detail: str


@_DOCUMENTED
class BatteryReport(TypedDict):
    remaining_pct: int | None
    voltage: float | None


@_DOCUMENTED
class GpsReport(TypedDict):
    fix_type: int | None
    satellites: int | None
    h_acc: float | None
    v_acc: float | None


@_DOCUMENTED
class SensorReport(TypedDict):
    unhealthy: list[str] | None
    """SYS_STATUS sensors present and enabled but not healthy, by name."""
    prearm_ok: bool | None
    warnings: list[str]
    """The vehicle's latest pre-arm warnings (STATUSTEXT)."""


@_DOCUMENTED
class LinkQualityReport(TypedDict):
    """One vehicle's link figures (`gcs.flight.link.quality.LinkQuality.report`)."""

    received: int
    lost: int
    reordered: int
    duplicates: int
    restarts: int
    loss_pct: float | None
    recent_loss_pct: float | None
    latency_ms: float | None
    jitter_ms: float | None


@_DOCUMENTED
class HealthReport(TypedDict):
    """What a vehicle reports of its fitness (`gcs.flight.safety.health.health_report`)."""

    battery: BatteryReport
    gps: GpsReport
    health: SensorReport
    link_quality: LinkQualityReport


@_DOCUMENTED
class VehicleSnapshot(TypedDict):
    """One vehicle of a flight's snapshot; the health keys once it has been heard."""

    id: str
    system_id: int
    phase: VehiclePhase
    autopilot: str | None
    """``px4`` or ``ardupilot``; None until an ``auto`` vehicle has been heard."""
    fault: str | None
    mode: str | None
    armed: bool
    heartbeat_age: float | None
    link_age: float | None
    position: list[float] | None
    velocity: list[float] | None
    tracking_error: float | None
    dropped: DropAction | None
    """``land`` or ``hold`` once a replan has dropped it."""
    battery: NotRequired[BatteryReport]
    gps: NotRequired[GpsReport]
    health: NotRequired[SensorReport]
    link_quality: NotRequired[LinkQualityReport]


@_DOCUMENTED
class ReplanDocument(TypedDict):
    """One in-flight replan as the flight shows it (`gcs.flight.replan.record.ReplanRecord`);
    the keys after ``horizon`` once it has switched."""

    id: int
    """The replan's number in this flight, from 1."""
    status: ReplanStatus
    """planning (the new plan is being made), switched (the stream flies it since
    `switch_time`) or missed (no verified plan by `switch_time`: the flight goes on with its
    plan; `why` and the `replan_missed` event say why)."""
    requested_at: float | None
    """Flight time of the request (s); None if the flight clock had not started."""
    switch_time: float
    """Flight time the new plan starts at (s)."""
    switch_tick: int
    """The stream's tick the new plan starts at."""
    lead_s: float
    """The lead it was given (s): it switches at the last tick within that time after the
    request."""
    planning_s: float | None
    """Planning time once planned (s)."""
    goals: dict[str, list[float]]
    """The new goals asked for: vehicle id -> [x, y, z]."""
    drop: list[str]
    """The vehicles dropped."""
    drop_action: DropAction
    """What the dropped vehicles do: land, or hold."""
    reason: str | None
    """Who asked, or which fault caused it."""
    vehicles: list[str]
    """The vehicles planned."""
    fixed: list[str]
    """The vehicles the others avoid on a known motion (the dropped ones, any vehicle in the
    air off the plan)."""
    faulty: list[str]
    """The faulty vehicles it flies the others around (policy replan)."""
    why: str | None
    """Why it was missed."""
    horizon: float | None
    """Once switched: the new plan's length (s) from `switch_time`."""
    request_to_switch_s: NotRequired[float]
    """From the request to the switch tick (s)."""
    min_separation_planned: NotRequired[float | None]
    """The new plan's verified minimum separation (m; None: not verified)."""
    separation_kept: NotRequired[float]
    """The separation the replan planned with (m)."""


@_DOCUMENTED
class FlightSnapshot(TypedDict):
    """A flight's live state (`gcs.flight.run.snapshot.flight_snapshot`)."""

    phase: FlightPhase
    flight_time: float | None
    horizon: float
    min_separation_live: float | None
    vehicles: list[VehicleSnapshot]
    events: int
    """How many events the flight has logged so far."""
    replan: ReplanDocument | None
    """The replan under way, or the last one (None before any)."""


def current_events(events: Iterable[Mapping[str, Any]]) -> list[FlightEvent]:
    """Stored events (decoded JSON) as `FlightEvent`s, each kind under its current value (a
    former one, `gcs.phases.FORMER_EVENT_KINDS`, read as the kind it is now; one this version
    does not know kept as stored, so an old record still reads)."""
    return [{"t": e["t"], "vehicle": e["vehicle"], "kind": _kind(e["kind"]),
             "detail": e["detail"]} for e in events]


def _kind(value: str) -> EventKind | str:
    """`value` as the event kind it names now, or as it is when no kind has that name."""
    try:
        return EventKind(value)
    except ValueError:
        return value


def finite_or_none(x: float | None) -> float | None:
    """`x` as a float, or None when it is None, NaN or infinite (JSON has no NaN/Infinity)."""
    return None if x is None or not math.isfinite(x) else float(x)
