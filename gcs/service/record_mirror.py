"""The flight record so far, carried from the vehicle process to the service in pieces.

The recorder lives with the flight in the vehicle process and grows by hundreds of entries
a second. The journal stores the record so far every few seconds; copying it whole each time
would cost the flight's process a pickle of the whole flight. So the service keeps a
`RecordMirror`: it asks for what was added since its cursor (`record_delta`, run where the
recorder lives, a few list slices) and appends it to its own copy. The document it gives is
the flight record's (`FlightRecorder.to_dict`'s shape), marked ``"partial": true``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gcs.flight.record import FlightRecorder

__all__ = ["RecordMirror", "record_delta"]

#: A vehicle's columns, as (delta key, recorder attribute, record section, record key).
COLUMNS = (
    ("sp_t", "setpoints", "t"), ("sp_tick", "setpoints", "tick"),
    ("sp_pos", "setpoints", "position_ned"), ("sp_vel", "setpoints", "velocity_ned"),
    ("sp_acc", "setpoints", "acceleration_ned"),
    ("tel_t", "telemetry", "t"), ("tel_pos", "telemetry", "position"),
    ("tel_vel", "telemetry", "velocity"),
)


def record_delta(recorder: FlightRecorder, cursor: dict[str, Any]) -> dict[str, Any]:
    """What `recorder` holds beyond `cursor` (a `RecordMirror.cursor()`): the meta, the new
    events and each vehicle's new column entries and mode changes. Runs on the vehicle loop,
    so the lists are not appended to meanwhile."""
    seen = cursor.get("vehicles", {})
    vehicles = []
    for v in recorder.vehicles.values():
        had = seen.get(v.id, {})
        columns = {name: list(getattr(v, name)[had.get(name, 0):]) for name, _, _ in COLUMNS}
        vehicles.append({"id": v.id, "system_id": v.system_id, "home": v.home,
                         "columns": columns, "modes": list(v.modes[had.get("modes", 0):])})
    return {"meta": dict(recorder.meta), "events": list(recorder.events[cursor.get("events", 0):]),
            "vehicles": vehicles}


class RecordMirror:
    """The service's copy of a flight record so far, grown by `record_delta`s."""

    def __init__(self) -> None:
        self._meta: dict[str, Any] = {}
        self._events: list[dict[str, Any]] = []
        self._vehicles: dict[str, dict[str, Any]] = {}

    def cursor(self) -> dict[str, Any]:
        """How much of the record this copy holds, for the next `record_delta`."""
        return {"events": len(self._events),
                "vehicles": {vid: {**{name: len(v["columns"][name]) for name, _, _ in COLUMNS},
                                   "modes": len(v["modes"])}
                             for vid, v in self._vehicles.items()}}

    def apply(self, delta: dict[str, Any]) -> None:
        """Append a `record_delta` taken at this copy's cursor."""
        self._meta = delta["meta"]
        self._events.extend(delta["events"])
        for v in delta["vehicles"]:
            mine = self._vehicles.setdefault(v["id"], {
                "id": v["id"], "system_id": v["system_id"], "home": v["home"],
                "columns": {name: [] for name, _, _ in COLUMNS}, "modes": []})
            mine["home"] = v["home"]
            for name, entries in v["columns"].items():
                mine["columns"][name].extend(entries)
            mine["modes"].extend(v["modes"])

    def snapshot(self) -> dict[str, Any]:
        """The record so far (JSON-ready with orjson), marked ``"partial": true``; the lists
        are this copy's own, read while nothing appends to them (the caller's loop)."""
        vehicles = []
        for v in self._vehicles.values():
            doc: dict[str, Any] = {"id": v["id"], "system_id": v["system_id"], "home": v["home"],
                                   "setpoints": {}, "telemetry": {}, "modes": v["modes"]}
            for name, section, key in COLUMNS:
                doc[section][key] = v["columns"][name]
            vehicles.append(doc)
        return {"format": "fleetplan-flight-record/1", "partial": True, **self._meta,
                "vehicles": vehicles, "events": self._events, "summary": None}
