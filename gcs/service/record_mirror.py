"""The flight record so far, carried from the vehicle process to the service in pieces.

The recorder lives with the flight in the vehicle process and grows by thousands of entries
a second on a large fleet. The journal stores the record so far every few seconds; copying it
whole each time would cost the flight's process a pickle of the whole flight, with its
interpreter lock held. So the service keeps a `RecordMirror`: about once a second it asks for
what was added since its cursor (`record_delta`, run where the recorder lives: list slices)
and appends it to its own copy. The entries are plain floats and ints (setpoints are made of
Python floats, `gcs.flight.link.setpoints`), which pickle fast: a second of 100 vehicles at 50 Hz
takes about 2-3 ms to pickle (numpy scalars took ten times longer), so the sender thread
holds the vehicle process's interpreter lock that long once a second. The document it gives
is the flight record's (`FlightRecorder.to_dict`'s shape, `gcs.flight.run.record.COLUMNS`),
marked ``"partial": true``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypedDict

from gcs.documents import FlightEvent
from gcs.flight.run.record import COLUMNS, RECORD_FORMAT

if TYPE_CHECKING:
    from gcs.flight.run.record import FlightRecorder

__all__ = ["RecordDelta", "RecordMirror", "VehicleDelta", "record_delta"]


class VehicleDelta(TypedDict):
    """One vehicle's part of a `RecordDelta`: its new column entries and mode changes."""

    id: str
    system_id: int
    home: list[float] | None
    columns: dict[str, list[Any]]
    """`COLUMNS`' attribute -> its entries beyond the cursor."""
    modes: list[dict[str, Any]]


class RecordDelta(TypedDict):
    """What a recorder holds beyond a cursor (`record_delta`)."""

    meta: dict[str, Any] | None
    """The record's meta when it changed, or None."""
    events: list[FlightEvent]
    vehicles: list[VehicleDelta]


def record_delta(recorder: FlightRecorder, cursor: dict[str, Any]) -> RecordDelta:
    """What `recorder` holds beyond `cursor` (a `RecordMirror.cursor()`): the meta when it
    changed, the new events and each vehicle's new column entries and mode changes.
    Runs on the vehicle loop, so the lists are not appended to meanwhile."""
    seen = cursor.get("vehicles", {})
    vehicles: list[VehicleDelta] = []
    for v in recorder.vehicles.values():
        had = seen.get(v.id, {})
        columns = {c.attribute: getattr(v, c.attribute)[had.get(c.attribute, 0):]
                   for c in COLUMNS}
        vehicles.append({"id": v.id, "system_id": v.system_id, "home": v.home,
                         "columns": columns, "modes": list(v.modes[had.get("modes", 0):])})
    meta = None if len(recorder.meta) == cursor.get("meta_keys") else dict(recorder.meta)
    return {"meta": meta, "events": list(recorder.events[cursor.get("events", 0):]),
            "vehicles": vehicles}


class RecordMirror:
    """The service's copy of a flight record so far, grown by `record_delta`s."""

    def __init__(self) -> None:
        self._meta: dict[str, Any] = {}
        self._events: list[FlightEvent] = []
        self._vehicles: dict[str, dict[str, Any]] = {}

    def cursor(self) -> dict[str, Any]:
        """How much of the record this copy holds, for the next `record_delta`."""
        return {"events": len(self._events), "meta_keys": len(self._meta),
                "vehicles": {vid: {**{c.attribute: len(v["columns"][c.attribute])
                                      for c in COLUMNS},
                                   "modes": len(v["modes"])}
                             for vid, v in self._vehicles.items()}}

    def apply(self, delta: RecordDelta) -> None:
        """Append a `record_delta` taken at this copy's cursor."""
        if delta["meta"] is not None:
            self._meta = delta["meta"]
        self._events.extend(delta["events"])
        for v in delta["vehicles"]:
            mine = self._vehicles.setdefault(v["id"], {
                "id": v["id"], "system_id": v["system_id"], "home": v["home"],
                "columns": {c.attribute: [] for c in COLUMNS}, "modes": []})
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
            for c in COLUMNS:  # vectors stay tuples: orjson writes them as the lists they are
                doc[c.section][c.key] = v["columns"][c.attribute]
            vehicles.append(doc)
        return {"format": RECORD_FORMAT, "partial": True, **self._meta,
                "vehicles": vehicles, "events": self._events, "summary": None}
