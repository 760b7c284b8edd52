"""Pausing a flight: the shared flight clock stops, every vehicle flying its plan track holds
one plan setpoint, and a resume hands each back its track where the clock stopped.

`Pausing` decides whether a pause or resume may happen (the flight's phase, an abort) and ends
a pause that lasts longer than `pause_limit` by the `pause_expiry` action; the setpoints
themselves change in `hold_fleet` and `release_fleet`, on the shared `Streamer` and
`FlightClock` (`gcs.flight.timeline.clock`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence

from gcs.errors import StateConflict
from gcs.flight.link.setpoints import SetpointTrack, hold_track
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.run.precedence import aborting_refusal
from gcs.flight.run.state import RunningFlight
from gcs.flight.timeline.clock import FlightClock, Pause
from gcs.flight.timeline.stream import Streamer
from gcs.phases import EventKind, FlightPhase

__all__ = ["Pausing", "hold_fleet", "release_fleet"]


class Pausing:
    """A flight's pauses: `pause`, `resume`, and the limit on how long one lasts."""

    def __init__(self, flight: RunningFlight) -> None:
        self.flight = flight
        self._limit: asyncio.Future[None] | None = None

    def pause(self, at: float | None = None) -> float:
        """Stop the shared flight clock: from the next tick every vehicle flying the plan
        holds the plan's setpoint of one plan time (at rest), so the fleet stays as
        separated as the plan is at that instant: the plan time reached, or `at` (flight
        time, s). Returns the plan time it holds. `StateConflict` unless the plan is being
        flown (and not already paused). After `pause_limit` s the `pause_expiry` action
        (land or hold) ends the flight."""
        flight = self.flight
        if flight.aborting is not None:
            raise aborting_refusal("pause", flight.aborting[0])
        if flight.clock.pause is not None:
            raise StateConflict("status", "already paused")
        if flight.phase != FlightPhase.FLYING or flight.clock.start is None:
            raise StateConflict("status", f"only a flying flight can be paused (phase "
                                          f"{flight.phase})")
        if flight.replanner is not None:
            flight.replanner.cancel("the flight was paused before the switch")
        streamer = _streamer(flight)
        pause = hold_fleet(streamer, flight.clock, flight.vehicles, flight.tracks, at)
        self._limit = asyncio.ensure_future(self._expire())
        flight.phase = FlightPhase.PAUSED
        t = pause.plan_tick / streamer.rate
        options = flight.options
        flight.context.emit(None, EventKind.PAUSE, f"flight clock stopped at t={t:.2f} s; "
                                                   f"{', '.join(pause.held)} holding (limit "
                                                   f"{options.pause_limit:g} s, then "
                                                   f"{options.pause_expiry})")
        return t

    def resume(self) -> float:
        """Restart the shared flight clock where `pause` stopped it; returns that plan time.
        `StateConflict` unless paused."""
        flight = self.flight
        if flight.aborting is not None:
            raise aborting_refusal("resume", flight.aborting[0])
        if flight.clock.pause is None:
            raise StateConflict("status", f"not paused (phase {flight.phase})")
        streamer = _streamer(flight)
        pause, paused = release_fleet(streamer, flight.clock, flight.vehicles, flight.tracks)
        self._cancel_limit()
        flight.phase = FlightPhase.FLYING
        t = pause.plan_tick / streamer.rate
        flight.context.emit(None, EventKind.RESUME, f"flight clock running again from "
                                                    f"t={t:.2f} s after {paused:.1f} s")
        return t

    def end(self) -> None:
        """Forget a pause (the flight is ending)."""
        self.flight.clock.end_pause()
        self._cancel_limit()

    async def _expire(self) -> None:
        options = self.flight.options
        await asyncio.sleep(options.pause_limit)
        action = options.pause_expiry
        self.flight.context.emit(None, EventKind.PAUSE_LIMIT, f"paused for "
                                                              f"{options.pause_limit:g} s: "
                                                              f"{action} all")
        await self.flight.abort(action, f"paused longer than {options.pause_limit:g} s")

    def _cancel_limit(self) -> None:
        if self._limit is not None:
            self._limit.cancel()
            self._limit = None


def _streamer(flight: RunningFlight) -> Streamer:
    assert flight.streamer is not None  # a flying flight streams
    return flight.streamer


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
