"""One vehicle's way into the air in a flight: connect, home, the pre-flight gate, message
rates, then prestream, OFFBOARD, arm and the climb to its start.

The executor (`gcs.flight.executor`) runs `connect_vehicle` for every vehicle, then
`prepare_vehicle` for every vehicle, concurrently; the PX4 commands themselves are the
primitives of `gcs.flight.vehicle`. Every deadline is on the flight's `StationStalls` clock.
"""

from __future__ import annotations

import asyncio

import numpy as np

from gcs import frames, px4
from gcs.errors import PreflightFailed
from gcs.flight import vehicle
from gcs.flight.fleetfile import FlightOptions
from gcs.flight.health import PreflightThresholds, preflight_problems
from gcs.flight.phases import EventKind, VehiclePhase
from gcs.flight.record import FlightRecorder
from gcs.flight.setpoints import hold_track, transfer_track
from gcs.flight.station import StationStalls
from gcs.flight.stream import Streamer
from gcs.flight.vehicle import Emit, VehicleStatus

__all__ = ["connect_vehicle", "preflight", "prepare_vehicle"]


async def connect_vehicle(v: VehicleStatus, options: FlightOptions,
                          world_origin: frames.Geodetic | None, recorder: FlightRecorder,
                          emit: Emit, stalls: StationStalls) -> None:
    """First HEARTBEAT and position, home in the world frame (from `world_origin` when the
    fleet file gives none), the pre-flight gate, and the message rates when asked for."""
    link = v.linked
    await vehicle.connect(link, v.spec, options.connect_timeout, stalls)
    if v.home is None:
        assert world_origin is not None
        v.home, source = await vehicle.resolve_home(link, v.id, world_origin, stalls)
        recorder.vehicles[v.id].home = v.home.tolist()
        emit(v.id, EventKind.HOME, f"from {source}: {np.round(v.home, 3).tolist()}")
    await preflight(v, options, emit, stalls)
    if options.message_rates == "request":
        answers = await vehicle.request_message_rates(
            link, vehicle.message_rates(options.position_rate_hz), stalls)
        emit(v.id, EventKind.MESSAGE_RATES, ", ".join(f"{k} {a}" for k, a in answers.items()))
    vehicle.refuse_other_claimants(link, v.spec)  # over the whole connect, not its start
    v.phase = VehiclePhase.CONNECTED
    mode = link.telemetry.mode
    emit(v.id, EventKind.CONNECTED, f"mode {mode.name if mode else '?'}, home "
                                    f"{np.round(v.home, 3).tolist()}")


async def preflight(v: VehicleStatus, options: FlightOptions, emit: Emit,
                    stalls: StationStalls | None = None) -> None:
    """The pre-flight gate (`gcs.flight.health`): wait up to `preflight_wait` for the
    vehicle to be fit; then refuse it (`PreflightFailed`), or with `preflight: override`
    record what was overridden and carry on."""
    limits = PreflightThresholds(min_battery_pct=options.min_battery_pct)
    link = v.linked
    if options.preflight == "check":
        await vehicle.wait_running(link, lambda t: not preflight_problems(t, limits),
                                   options.preflight_wait, stalls)
    problems = preflight_problems(link.telemetry, limits)
    if not problems:
        return
    if options.preflight == "check":
        raise PreflightFailed(v.id, problems)
    emit(v.id, EventKind.PREFLIGHT_OVERRIDE, "; ".join(problems))


async def prepare_vehicle(v: VehicleStatus, streamer: Streamer, options: FlightOptions,
                          yaw_ned: float, emit: Emit, stalls: StationStalls) -> None:
    """Stream setpoints holding the vehicle where it is, then OFFBOARD, arm, and stream the
    climb from there to its start (`v.start_ned`)."""
    link = v.linked
    here = np.asarray(link.telemetry.position_ned, dtype=float)
    streamer.assign(v.id, link, hold_track(here, yaw_ned, options.rate_hz))
    await asyncio.sleep(options.prestream)
    v.phase = VehiclePhase.ARMING
    await vehicle.set_mode(link, px4.OFFBOARD, confirm_timeout=options.heartbeat_timeout,
                           retry_for=vehicle.MODE_RETRY_FOR, stalls=stalls)
    emit(v.id, EventKind.MODE, f"{px4.OFFBOARD.name} confirmed")
    v.expect_offboard = True

    def attempt() -> None:
        v.arm_sent = True

    def accepted() -> None:
        v.armed_by_us = True

    attempts = await vehicle.arm(link, timeout=options.arm_timeout,
                                 confirm_timeout=options.heartbeat_timeout,
                                 on_attempt=attempt, on_accepted=accepted, stalls=stalls)
    emit(v.id, EventKind.ARMED, f"after {attempts} attempt(s)")
    assert v.start_ned is not None
    track = transfer_track(here, v.start_ned, options.climb_speed, yaw_ned, options.rate_hz)
    streamer.assign(v.id, link, track)
    v.phase = VehiclePhase.CLIMBING
    emit(v.id, EventKind.CLIMB, f"to start, {track.duration:.1f} s")
