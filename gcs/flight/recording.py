"""What goes into the flight record from the links and the streamer while a flight runs.

`FlightRecording` is the listener of every vehicle's link (positions in the world frame, mode
and armed changes, STATUSTEXT) and of the streamer (each setpoint sent, with its tick);
`finish_record` fills the record's meta block and summary when the flight ends.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from gcs import frames
from gcs.flight.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link import VehicleLink
from gcs.flight.margin import MarginCheck
from gcs.flight.phases import EventKind
from gcs.flight.record import FlightRecorder, summarise
from gcs.flight.setpoints import Setpoint
from gcs.flight.stream import Streamer
from gcs.flight.vehicle import Emit, VehicleStatus
from planner import Plan

__all__ = ["FlightRecording", "finish_record"]


class FlightRecording:
    """The recorder's link and streamer listeners; times are seconds on the GCS clock
    (`origin()` is its zero, in monotonic seconds)."""

    def __init__(self, recorder: FlightRecorder, vehicles: Mapping[str, VehicleStatus],
                 origin: Callable[[], float], emit: Emit) -> None:
        self.recorder = recorder
        self.vehicles = vehicles
        self.origin = origin
        self.emit = emit

    def on_send(self, vehicle_id: str, tick: int, setpoint: Setpoint, sent: float) -> None:
        """A setpoint went out in `tick` (the streamer's listener)."""
        self.recorder.vehicles[vehicle_id].add_setpoint(round(sent - self.origin(), 5), tick,
                                                        setpoint)

    def on_message(self, link: VehicleLink, msg: Any, now: float) -> None:
        """A message arrived on `link` (the link's listener)."""
        kind = msg.get_type()
        v = self.vehicles[link.vehicle_id]
        rec = self.recorder.vehicles[v.id]
        t = round(now - self.origin(), 5)
        if kind == "LOCAL_POSITION_NED" and v.home is not None:
            rec.tel_t.append(t)
            rec.tel_pos.append(frames.ned_to_world((msg.x, msg.y, msg.z), v.home).tolist())
            rec.tel_vel.append(frames.ned_vector_to_world((msg.vx, msg.vy, msg.vz)).tolist())
        elif kind == "HEARTBEAT" and msg.get_srcComponent() == link.component_id:
            tel = link.telemetry
            mode = tel.mode.name if tel.mode is not None else None
            if mode != v.last_mode or tel.armed != v.last_armed:
                v.last_mode, v.last_armed = mode, tel.armed
                rec.modes.append({"t": t, "mode": mode, "armed": tel.armed})
                self.emit(v.id, EventKind.MODE_CHANGE,
                          f"{mode}, {'armed' if tel.armed else 'disarmed'}")
        elif kind == "STATUSTEXT":  # the link has joined a chunked text: its latest is whole
            self.emit(v.id, EventKind.STATUSTEXT, link.telemetry.statustexts[-1])


def finish_record(recorder: FlightRecorder, plan: Plan, fleet: FleetSpec,
                  options: FlightOptions, vehicles: list[VehicleStatus], *,
                  flight_start: float | None, pauses: list[list[float | None]], now: float,
                  margin: MarginCheck, streamer: Streamer | None,
                  error: BaseException | None) -> dict[str, Any]:
    """Fill the record's meta block and summary; returns the record document."""
    scenario = plan.scenario
    recorder.meta = {
        "plan": scenario.to_dict(),
        "fleet": fleet.to_dict(),
        "options": options.to_dict(),
        "flight_start": flight_start,
        "mission_start": flight_start,  # the same, for consumers of that key
        "pauses": pauses,
        "horizon": scenario.horizon,
        "error": None if error is None else {
            "type": type(error).__name__, "message": str(error) or type(error).__name__},
    }
    recorder.summary = summarise(
        recorder, plan, options, vehicles,
        flight_start=flight_start, pauses=pauses, now=now,
        margin=margin, position_error=fleet.position_error,
        missed_ticks=streamer.missed_ticks if streamer is not None else 0,
        lateness=streamer.lateness if streamer is not None else None, error=error)
    return recorder.to_dict()
