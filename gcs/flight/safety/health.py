"""Vehicle health from telemetry, and the pre-flight gate.

`health_report(telemetry)` turns what a vehicle reported into the JSON shown per vehicle by
`GET /api/vehicles` and the executor's snapshot:

- ``battery``: remaining % and voltage (SYS_STATUS; BATTERY_STATUS when sent);
- ``gps``: fix type, satellites, horizontal / vertical accuracy (GPS_RAW_INT h_acc, v_acc, m);
- ``health``: sensors present and enabled but not healthy (SYS_STATUS bits, by name), the
  pre-arm check bit, and the vehicle's latest warnings (STATUSTEXT, severity WARNING or worse);
- ``link_quality``: messages received, lost, reordered and repeated (from the MAVLink
  sequence numbers), loss % in all and over the last 5 s, latency and jitter (ms;
  `gcs.flight.link.quality`).

`preflight_problems(telemetry, thresholds)` lists what must stop a flight before anything is
armed: no HEARTBEAT or position (a missing vehicle), battery below `min_battery_pct`, an
enabled sensor reported unhealthy, link loss above `max_link_loss_pct`. The pre-arm bit is
*not* a gate: PX4 clears it while its estimator settles after boot (the first 4-5 s), and
arming is retried through that; its refusal is reported with PX4's own words.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs.documents import HealthReport, finite_or_none
from gcs.flight.link.telemetry import Telemetry
from gcs.wire import mavlink

__all__ = ["PreflightThresholds", "health_report", "preflight_problems", "sensor_names"]

#: SYS_STATUS sensor bits by short name (MAV_SYS_STATUS_SENSOR_*), for messages.
_SENSOR_BITS = {
    name.removeprefix("MAV_SYS_STATUS_SENSOR_").removeprefix("MAV_SYS_STATUS_").lower():
    value for name, value in vars(mavlink).items()
    if name.startswith(("MAV_SYS_STATUS_SENSOR_", "MAV_SYS_STATUS_AHRS",
                        "MAV_SYS_STATUS_TERRAIN", "MAV_SYS_STATUS_REVERSE_MOTOR",
                        "MAV_SYS_STATUS_LOGGING", "MAV_SYS_STATUS_RECOVERY_SYSTEM"))
    and isinstance(value, int) and value > 0 and not name.endswith("_ENUM_END")
}


def sensor_names(bits: int) -> list[str]:
    """Names of the SYS_STATUS sensor bits set in `bits`."""
    return sorted(name for name, bit in _SENSOR_BITS.items() if bits & bit)


@dataclass(frozen=True)
class PreflightThresholds:
    """Limits of the pre-flight gate."""

    min_battery_pct: float = 30.0
    max_link_loss_pct: float = 20.0


def _sensors(tel: Telemetry) -> tuple[int | None, int | None]:
    """(unhealthy enabled sensor bits, pre-arm check state 1/0) or Nones before SYS_STATUS."""
    if tel.sensors_present is None or tel.sensors_enabled is None or tel.sensors_health is None:
        return None, None
    enabled = tel.sensors_present & tel.sensors_enabled
    prearm = mavlink.MAV_SYS_STATUS_PREARM_CHECK
    unhealthy = enabled & ~tel.sensors_health & ~prearm
    prearm_ok = None if not enabled & prearm else int(bool(tel.sensors_health & prearm))
    return unhealthy, prearm_ok


def link_loss_pct(tel: Telemetry) -> float | None:
    """Share of the vehicle's messages lost on the way (%), from the sequence numbers
    (reordered and repeated messages are not lost: `gcs.flight.link.quality`)."""
    loss = tel.quality.counter.loss
    return None if loss is None else 100.0 * loss


def health_report(tel: Telemetry) -> HealthReport:
    """battery, gps, health and link_quality of one vehicle (JSON-ready, None = unknown)."""
    unhealthy, prearm = _sensors(tel)
    return {
        "battery": {
            "remaining_pct": tel.battery_remaining,
            "voltage": finite_or_none(tel.battery_voltage),
        },
        "gps": {
            "fix_type": tel.gps_fix_type,
            "satellites": tel.gps_satellites,
            "h_acc": finite_or_none(tel.gps_h_acc),
            "v_acc": finite_or_none(tel.gps_v_acc),
        },
        "health": {
            "unhealthy": None if unhealthy is None else sensor_names(unhealthy),
            "prearm_ok": None if prearm is None else bool(prearm),
            "warnings": list(tel.warnings),
        },
        "link_quality": tel.quality.report(),
    }


def preflight_problems(tel: Telemetry, thresholds: PreflightThresholds | None = None, *,
                       require_presence: bool = True) -> list[str]:
    """Why this vehicle must not fly now (empty: nothing known against it);
    `require_presence` False skips "missing" and "no position" (not heard from yet)."""
    limits = thresholds or PreflightThresholds()
    problems = []
    if require_presence and tel.heartbeat_time is None:
        problems.append("missing: no HEARTBEAT")
    if require_presence and tel.position_ned is None:
        problems.append("no position estimate (no LOCAL_POSITION_NED)")
    if tel.battery_remaining is not None and tel.battery_remaining < limits.min_battery_pct:
        problems.append(f"battery {tel.battery_remaining}% (below "
                        f"{limits.min_battery_pct:g}%)")
    unhealthy, _ = _sensors(tel)
    if unhealthy:
        problems.append(f"unhealthy: {', '.join(sensor_names(unhealthy))}")
    loss = link_loss_pct(tel)
    if loss is not None and tel.seq_received >= 50 and loss > limits.max_link_loss_pct:
        problems.append(f"link loss {loss:.0f}% (above {limits.max_link_loss_pct:g}%)")
    return problems
