"""The JSON documents a flight hands out, typed once: its events, its live snapshot and its
replan objects.

They are TypedDicts (plain dicts at run time), so the record, the REST API, the page and
``fleetplan fly`` read the same keys the flight writes, and mypy checks both ends. Times are
seconds (events on the GCS clock, the rest in flight time), positions in the world frame
(ENU, m); None is unknown.
"""

from __future__ import annotations

import math
from typing import NotRequired, TypedDict

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
    "finite_or_none",
]


class FlightEvent(TypedDict):
    """One line of a flight's event log (`gcs.phases.EventKind` names its kind)."""

    t: float
    vehicle: str | None
    """The vehicle it is about; None for the fleet."""
    kind: str
    detail: str


class BatteryReport(TypedDict):
    remaining_pct: int | None
    voltage: float | None


class GpsReport(TypedDict):
    fix_type: int | None
    satellites: int | None
    h_acc: float | None
    v_acc: float | None


class SensorReport(TypedDict):
    unhealthy: list[str] | None
    """SYS_STATUS sensors present and enabled but not healthy, by name."""
    prearm_ok: bool | None
    warnings: list[str]
    """The vehicle's latest pre-arm warnings (STATUSTEXT)."""


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


class HealthReport(TypedDict):
    """What a vehicle reports of its fitness (`gcs.flight.safety.health.health_report`)."""

    battery: BatteryReport
    gps: GpsReport
    health: SensorReport
    link_quality: LinkQualityReport


class VehicleSnapshot(TypedDict):
    """One vehicle of a flight's snapshot; the health keys once it has been heard."""

    id: str
    system_id: int
    phase: str
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
    dropped: str | None
    """``land`` or ``hold`` once a replan has dropped it."""
    battery: NotRequired[BatteryReport]
    gps: NotRequired[GpsReport]
    health: NotRequired[SensorReport]
    link_quality: NotRequired[LinkQualityReport]


class ReplanDocument(TypedDict):
    """One in-flight replan as the flight shows it (`gcs.flight.replan.record.ReplanRecord`);
    the keys after ``horizon`` once it has switched."""

    id: int
    status: str
    """`gcs.phases.ReplanStatus`: planning, switched or missed."""
    requested_at: float | None
    switch_time: float
    switch_tick: int
    lead_s: float
    planning_s: float | None
    goals: dict[str, list[float]]
    drop: list[str]
    drop_action: str
    reason: str | None
    vehicles: list[str]
    fixed: list[str]
    faulty: list[str]
    why: str | None
    horizon: float | None
    request_to_switch_s: NotRequired[float]
    min_separation_planned: NotRequired[float | None]
    separation_kept: NotRequired[float]


class FlightSnapshot(TypedDict):
    """A flight's live state (`gcs.flight.run.snapshot.flight_snapshot`)."""

    phase: str
    flight_time: float | None
    horizon: float
    min_separation_live: float | None
    vehicles: list[VehicleSnapshot]
    events: int
    """How many events the flight has logged so far."""
    replan: ReplanDocument | None
    """The replan under way, or the last one (None before any)."""


def finite_or_none(x: float | None) -> float | None:
    """`x` as a float, or None when it is None, NaN or infinite (JSON has no NaN/Infinity)."""
    return None if x is None or not math.isfinite(x) else float(x)
