"""A flight's JSON-ready live state, as the REST API, the page and ``fleetplan fly`` show it.

Positions are in the world frame; ``flight_time`` is the flight clock.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

from gcs import frames
from gcs.documents import FlightSnapshot, ReplanDocument, VehicleSnapshot, finite_or_none
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.safety.health import health_report
from gcs.phases import FlightPhase

__all__ = ["flight_snapshot", "vehicle_snapshot"]


def vehicle_snapshot(v: VehicleStatus, now: float) -> VehicleSnapshot:
    """One vehicle: phase, fault, mode, armed, heartbeat and link age, world position and
    velocity, tracking error, health."""
    tel = v.link.telemetry if v.link is not None else None
    position = None
    velocity = None
    if tel is not None and tel.position_ned is not None and v.home is not None:
        position = frames.ned_to_world(tel.position_ned, v.home).tolist()
        if tel.velocity_ned is not None:
            velocity = frames.ned_vector_to_world(tel.velocity_ned).tolist()
    age = v.link.heartbeat_age(now) if v.link is not None else math.inf
    silent = v.link.link_age(now) if v.link is not None else math.inf
    snapshot: VehicleSnapshot = {
        "id": v.id, "system_id": v.spec.system_id, "phase": v.phase,
        "autopilot": (tel.autopilot_named(v.spec.autopilot) if tel is not None
                      else None if v.spec.autopilot == "auto" else v.spec.autopilot),
        "fault": v.fault,
        "mode": tel.mode.name if tel is not None and tel.mode is not None else None,
        "armed": bool(tel.armed) if tel is not None else False,
        "heartbeat_age": None if math.isinf(age) else round(age, 3),
        "link_age": None if math.isinf(silent) else round(silent, 3),
        "position": position, "velocity": velocity,
        "tracking_error": finite_or_none(v.tracking_error),
        "dropped": v.dropped,
    }
    return snapshot if tel is None else {**snapshot, **health_report(tel)}


def flight_snapshot(phase: FlightPhase, flight_time: float | None, horizon: float,
                    min_separation: float, vehicles: Sequence[VehicleStatus],
                    events: int, replan: ReplanDocument | None = None) -> FlightSnapshot:
    """The whole flight: phase, flight time, horizon (the end of the plan flown now, a
    switched replan's), live minimum separation, vehicles, number of events so far, and the
    replan under way or the last one (`gcs.flight.replan.replan`; None before any)."""
    now = time.monotonic()
    return {
        "phase": phase,
        "flight_time": flight_time,
        "horizon": horizon,
        "min_separation_live": finite_or_none(min_separation),
        "vehicles": [vehicle_snapshot(v, now) for v in vehicles],
        "events": events,
        "replan": replan,
    }
