"""The flight record: what was sent, what the vehicles reported, what happened, and a summary
(`gcs.flight.run.summary`).

Times are seconds on the GCS clock (0 when the executor started running); ``flight_start`` is
the GCS-clock time of flight time 0 (null if the plan never started; records written before
this key carry it as ``mission_start``), so flight time = t - flight_start, less the time
spent in ``pauses`` ([start, end] each, GCS clock) before t (`plan_times`). Positions are
in the world frame (ENU, m) unless the key says ``_ned``. JSON layout::

    {"format": "fleetplan-flight-record/2", "plan": {...scenario echo...},
     "fleet": {...}, "options": {...}, "flight_start": 12.3,
     "pauses": [[20.1, 25.3]],
     "horizon": 30.0,
     "error": null | {"type": "ArmingRefused", "message": "..."},
     "vehicles": [{"id", "system_id", "home", "failsafe": {...} (once set),
                   "setpoints": {"t": [...], "tick": [...], "position_ned": [[x,y,z]...],
                                 "velocity_ned": [...], "acceleration_ned": [...]},
                   "telemetry": {"t": [...], "position": [...], "velocity": [...]},
                   "modes": [{"t", "mode", "armed"}...]}...],
     "events": [{"t", "vehicle", "kind", "detail"}...],
     "replans": [{"id", "status", "requested_at", "switch_time", "switch_tick", "lead_s",
                  "planning_s", "goals", "drop", "drop_action", "reason", "why", ...,
                  "plan": {...plan document...} | null,
                  "separation_across_switch": {"min", "at", "window"} | null}...],
     "summary": {"completed", "goal_error_max", "tracking_error_max",
                 "min_separation_measured", "setpoint_rate_hz", "jitter_p99_ms",
                 "aborted_at", "after_abort_s", "dropped", ...}}

Format 2 adds ``replans`` (every in-flight replan, `gcs.flight.replan.replan`; a switched one with
the plan flown from its switch tick and the separation measured across it) and the
summary's ``dropped``; ``horizon`` is the end of the last plan flown, in flight time.

The summary is computed from the recorded data by `gcs.flight.run.summary.summarise`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from gcs.documents import FlightEvent
from gcs.flight.link.setpoints import Setpoint
from gcs.phases import EventKind

if TYPE_CHECKING:
    pass

__all__ = ["COLUMNS", "RECORD_FORMAT", "Column", "FlightRecorder", "VehicleRecord", "gcs_time",
           "plan_times"]


#: The flight record's format name (its ``format`` key).
RECORD_FORMAT = "fleetplan-flight-record/2"


@dataclass(frozen=True)
class Column:
    """One recorded column of a vehicle: its `VehicleRecord` attribute, where it sits in the
    JSON (section, key), and the numbers per entry (1, or 3 for a vector)."""

    attribute: str
    section: str
    key: str
    width: int


#: A vehicle's recorded columns, in the JSON's order (`VehicleRecord.to_dict`).
COLUMNS = (
    Column("sp_t", "setpoints", "t", 1), Column("sp_tick", "setpoints", "tick", 1),
    Column("sp_pos", "setpoints", "position_ned", 3),
    Column("sp_vel", "setpoints", "velocity_ned", 3),
    Column("sp_acc", "setpoints", "acceleration_ned", 3),
    Column("tel_t", "telemetry", "t", 1), Column("tel_pos", "telemetry", "position", 3),
    Column("tel_vel", "telemetry", "velocity", 3),
)


@dataclass
class VehicleRecord:
    """One vehicle's recorded streams (columns as lists while flying)."""

    id: str
    system_id: int
    home: list[float] | None = None
    autopilot: str | None = None
    """The autopilot it was flown as (``px4`` or ``ardupilot``), once connected."""
    sp_t: list[float] = field(default_factory=list)
    sp_tick: list[int] = field(default_factory=list)
    sp_pos: list[tuple[float, float, float]] = field(default_factory=list)
    sp_vel: list[tuple[float, float, float]] = field(default_factory=list)
    sp_acc: list[tuple[float, float, float]] = field(default_factory=list)
    tel_t: list[float] = field(default_factory=list)
    tel_pos: list[list[float]] = field(default_factory=list)
    tel_vel: list[list[float]] = field(default_factory=list)
    modes: list[dict[str, Any]] = field(default_factory=list)
    failsafe: dict[str, Any] | None = None
    """What it does without the station, as set before arming (`loss_timeout`,
    `action_delay`, `action`, whether the station `set` it, and `why`)."""

    def add_setpoint(self, t: float, tick: int, sp: Setpoint) -> None:
        self.sp_t.append(t)
        self.sp_tick.append(tick)
        self.sp_pos.append(sp.position)
        self.sp_vel.append(sp.velocity)
        self.sp_acc.append(sp.acceleration)

    def telemetry_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(self.tel_t, dtype=float)
        p = np.asarray(self.tel_pos, dtype=float).reshape(-1, 3)
        return t, p

    def to_dict(self) -> dict[str, Any]:
        doc: dict[str, Any] = {"id": self.id, "system_id": self.system_id, "home": self.home,
                               "autopilot": self.autopilot, "setpoints": {}, "telemetry": {},
                               "modes": self.modes}
        if self.failsafe is not None:
            doc["failsafe"] = self.failsafe
        for column in COLUMNS:
            values = getattr(self, column.attribute)
            doc[column.section][column.key] = (
                values if column.width == 1 else [list(v) for v in values])
        return doc


class FlightRecorder:
    """Collects a flight's record; `to_dict` gives the JSON document."""

    def __init__(self, ids: list[str], system_ids: list[int]) -> None:
        self.vehicles = {vid: VehicleRecord(vid, sid) for vid, sid in
                         zip(ids, system_ids, strict=True)}
        self.events: list[FlightEvent] = []
        self.summary: dict[str, Any] = {}
        self.meta: dict[str, Any] = {}
        self.goal_settle_s = 0.0
        """Seconds the hold at the goals was extended for vehicles still arriving
        (`FlightOptions.goal_settle_max`): the summary's window includes them."""

    def event(self, t: float, vehicle: str | None, kind: EventKind, detail: str = ""
              ) -> FlightEvent:
        entry: FlightEvent = {"t": round(t, 4), "vehicle": vehicle, "kind": kind, "detail": detail}
        self.events.append(entry)
        return entry

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": RECORD_FORMAT,
            **self.meta,
            "vehicles": [v.to_dict() for v in self.vehicles.values()],
            "events": self.events,
            "summary": self.summary,
        }


def gcs_time(flight_time: float, flight_start: float,
             pauses: Sequence[Sequence[float | None]]) -> float:
    """The GCS-clock instant of `flight_time` (the inverse of `plan_times`)."""
    t = flight_start + flight_time
    for start, end in pauses:
        assert start is not None
        if t > start:
            t += (math.inf if end is None else end) - start
    return t


def plan_times(t: np.ndarray, flight_start: float,
               pauses: Sequence[Sequence[float | None]]) -> np.ndarray:
    """Flight (plan) time of GCS-clock instants `t`: the clock stood still during each
    [start, end] of `pauses` (end None: still paused)."""
    t = np.asarray(t, dtype=float)
    tau = t - flight_start
    for start, end in pauses:
        assert start is not None
        length = math.inf if end is None else end - start
        tau = tau - np.clip(t - start, 0.0, length)
    return tau
