"""What a pause does to the streams: every vehicle flying its plan track holds one plan
setpoint, and a resume hands each back its track where the clock stopped.

The executor decides whether a pause or resume may happen (its phase, an abort, the pause
limit) and tells it; the setpoints themselves change here, on the shared `Streamer` and
`FlightClock` (`gcs.flight.run.clock`).
"""

from __future__ import annotations

from collections.abc import Sequence

from gcs.flight.link.setpoints import SetpointTrack, hold_track
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.run.clock import FlightClock, Pause
from gcs.flight.run.stream import Streamer

__all__ = ["hold_fleet", "release_fleet"]


def hold_fleet(streamer: Streamer, clock: FlightClock, vehicles: Sequence[VehicleStatus],
               tracks: Sequence[SetpointTrack], at: float | None = None) -> Pause:
    """Stop `clock` from the next tick and set every vehicle still streamed its plan track
    to hold that track's setpoint of the plan time reached (or of flight time `at`); a
    vehicle on another track (landing, stopped) is left as it is. Returns the pause
    (`held`: the vehicles set to hold)."""
    tick = streamer.next_tick()
    pause = clock.stop(tick, None if at is None else round(at * streamer.rate))
    for v, track in zip(vehicles, tracks, strict=True):
        assignment = streamer.assignments.get(v.id)
        if assignment is None or assignment.track is not track:
            continue  # landing (land_faulty) or already stopped: not ours to hold
        sp = track.at(pause.plan_tick)
        streamer.assign(v.id, assignment.link, hold_track(sp.position, sp.yaw, streamer.rate),
                        tick)
        pause.held.append(v.id)
    return pause


def release_fleet(streamer: Streamer, clock: FlightClock, vehicles: Sequence[VehicleStatus],
                  tracks: Sequence[SetpointTrack]) -> tuple[Pause, float]:
    """Restart `clock` from the next tick and give every held vehicle still streamed (and
    not faulty) its plan track again from the plan tick held. Returns the pause that ended
    and its length (s)."""
    tick = streamer.next_tick()
    pause, paused = clock.restart(tick)
    for v, track in zip(vehicles, tracks, strict=True):
        if v.id in pause.held and v.id in streamer.assignments and v.fault is None:
            streamer.assign(v.id, streamer.assignments[v.id].link, track,
                            tick - pause.plan_tick)
    return pause, paused
