"""What goes into the flight record from the links and the streamer while a flight runs.

`FlightRecording` is the listener of every vehicle's link (positions in the world frame, mode
and armed changes, STATUSTEXT) and of the streamer (each setpoint sent, with its tick);
`finish_record` fills the record's meta block and summary when the flight ends.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from gcs import frames
from gcs.documents import ReplanDocument, finite_or_none
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.setpoints import Setpoint
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.flight.run.record import FlightRecorder
from gcs.flight.run.summary import STALE_REPORT_S, measured_min_separation, summarise
from gcs.flight.safety.margin import MarginCheck
from gcs.flight.timeline.flown import FlownPlans
from gcs.flight.timeline.stream import Streamer
from gcs.phases import EventKind
from planner import Plan
from planner.model.scenario import Scenario

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
                  error: BaseException | None, flown: FlownPlans | None = None,
                  replans: Sequence[ReplanDocument] = (),
                  flown_plans: Mapping[int, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Fill the record's meta block and summary; returns the record document. `flown`: the
    flight's plans and the motions off them (`gcs.flight.timeline.flown`), `replans` its replan
    objects, `flown_plans` each switched one's plan document and switch instant (GCS
    clock)."""
    scenario = plan.scenario
    flown = flown or FlownPlans.of(plan)
    recorder.meta = {
        "plan": scenario.to_dict(),
        "fleet": fleet.to_dict(),
        "options": options.to_dict(),
        "flight_start": flight_start,
        "pauses": pauses,
        "horizon": flown.horizon,
        "error": None if error is None else {
            "type": type(error).__name__, "message": str(error) or type(error).__name__},
    }
    recorder.summary = summarise(
        recorder, plan, options, vehicles,
        flight_start=flight_start, pauses=pauses, now=now,
        margin=margin, position_error=fleet.position_error,
        missed_ticks=streamer.missed_ticks if streamer is not None else 0,
        lateness=streamer.lateness if streamer is not None else None, error=error,
        planned=flown.position, horizon=flown.horizon,
        off_plan={vid: m.start for vid, m in flown.motions.items()})
    recorder.meta["replans"] = [
        replan_entry(recorder, obj, (flown_plans or {}).get(obj["id"]), scenario, options)
        for obj in replans]
    return recorder.to_dict()


#: The separation across a switch is measured this long before and after it (s).
SWITCH_WINDOW_S = 2.0


def replan_entry(recorder: FlightRecorder, obj: ReplanDocument,
                 flown: Mapping[str, Any] | None, scenario: Scenario, options: FlightOptions
                 ) -> dict[str, Any]:
    """One replan for the record: its object; a switched one's plan document and the
    minimum separation measured within `SWITCH_WINDOW_S` of its switch (the plan's
    metric, every vehicle in the record)."""
    entry: dict[str, Any] = {**obj, "plan": None, "separation_across_switch": None}
    if flown is None:
        return entry
    entry["plan"] = flown["plan"]
    at = float(flown["switch_gcs"])
    times, positions = zip(*(rec.telemetry_arrays() for rec in recorder.vehicles.values()),
                           strict=True)
    scale = np.asarray(scenario.separation_scale, dtype=float)
    window = (at - SWITCH_WINDOW_S, at + SWITCH_WINDOW_S)
    closest, instant = measured_min_separation(list(times), list(positions), window[0],
                                               window[1], options.rate_hz, scale,
                                               stale_after=STALE_REPORT_S)
    entry["separation_across_switch"] = {
        "min": finite_or_none(closest), "at": finite_or_none(instant),
        "switch_at": round(at, 4), "window": [round(w, 4) for w in window]}
    return entry
