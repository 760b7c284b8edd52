"""One vehicle's way into the air in a flight: connect, home, the pre-flight gate, message
rates, its geofence, then prestream, OFFBOARD, arm and the climb to its start.

The executor (`gcs.flight.run.executor`) runs `connect_vehicle` for every vehicle, then
`fence_fleet` (`fence_vehicle` for every vehicle), then `prepare_vehicle` for every vehicle,
concurrently; the PX4 commands themselves are the
primitives of `gcs.flight.procedure.vehicle`. Every deadline is on the flight's `StationStalls`
clock.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence

import numpy as np

from gcs import frames, px4
from gcs.errors import GeofenceFailed, PreflightFailed
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.setpoints import hold_track, transfer_track
from gcs.flight.link.station import StationStalls
from gcs.flight.procedure import vehicle
from gcs.flight.procedure.fence_upload import send_fence
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.flight.run.record import FlightRecorder
from gcs.flight.run.stream import Streamer
from gcs.flight.safety.health import PreflightThresholds, preflight_problems
from gcs.geofence import WorldFence, fence_items
from gcs.phases import EventKind, VehiclePhase

__all__ = ["FENCE_TRANSFERS", "connect_vehicle", "fence_fleet", "fence_origin", "fence_vehicle",
           "preflight", "prepare_vehicle"]

#: Whole uploads (with read-back) of a vehicle's fence before the flight is refused, and the
#: wait before each next (s): every message of one upload is already resent 5 times, so a
#: next upload is for a link that lost a run of them; it waits until the vehicle has given
#: the failed transfer up (PX4 refuses another meanwhile).
FENCE_TRANSFERS = 3
FENCE_RETRY_WAIT_S = px4.MISSION_PROTOCOL_TIMEOUT_S + 0.5


async def connect_vehicle(v: VehicleStatus, options: FlightOptions,
                          world_origin: frames.Geodetic | None, recorder: FlightRecorder,
                          emit: Emit, stalls: StationStalls, *, take_over: bool = False) -> None:
    """First HEARTBEAT and position, home in the world frame (from `world_origin` when the
    fleet file gives none), the pre-flight gate, and the message rates when asked for
    (take_over: an armed vehicle is taken, not refused)."""
    link = v.linked
    await vehicle.connect(link, v.spec, options.connect_timeout, stalls, armed_ok=take_over)
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
    """The pre-flight gate (`gcs.flight.safety.health`): wait up to `preflight_wait` for the
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


def fence_origin(v: VehicleStatus, world_origin: frames.Geodetic | None
                 ) -> tuple[np.ndarray, frames.Geodetic] | None:
    """Where `v`'s fence is placed on the Earth from: (its home in the world frame, the
    geodetic point of that home) by its GPS_GLOBAL_ORIGIN, else (0, the fleet's
    world_origin); None when neither is known."""
    gps = v.linked.telemetry.gps_origin
    if gps is not None and v.home is not None:
        return v.placed, frames.Geodetic(*gps)
    if world_origin is not None:
        return np.zeros(3), world_origin
    return None


async def fence_fleet(vehicles: Sequence[VehicleStatus], fence: WorldFence,
                      options: FlightOptions, world_origin: frames.Geodetic | None,
                      emit: Emit, stalls: StationStalls) -> None:
    """The fleet option `geofence` applied: upload `fence` to every vehicle, or say why not
    (`GeofenceFailed` when an explicit upload has no origin or fails)."""
    if options.geofence == "skip":
        emit(None, EventKind.GEOFENCE_SKIPPED, "fleet option geofence: skip")
        return
    await asyncio.gather(*(vehicle.ask_origin(v.linked, stalls) for v in vehicles))
    missing = [v.id for v in vehicles if fence_origin(v, world_origin) is None]
    if missing:
        why = (f"no geodetic origin for {', '.join(missing)}: no GPS_GLOBAL_ORIGIN reported "
               f"after {vehicle.ORIGIN_TRIES} requests and no world_origin in the fleet file")
        if options.geofence == "upload":
            raise GeofenceFailed(missing[0], f"geofence: upload asked, but {why}")
        if len(missing) < len(vehicles):  # the others have GPS: this one's link lost it
            raise GeofenceFailed(missing[0], f"{why}, while the others reported theirs (a "
                                             f"lossy link?); the flight is not flown without "
                                             f"the fence (fleet option geofence: skip flies "
                                             f"without one)")
        emit(None, EventKind.GEOFENCE_SKIPPED, f"not uploaded: {why}")
        return
    if fence.not_fenced:
        emit(None, EventKind.GEOFENCE_NOT_FENCED,
             f"obstacles not reaching the ground cannot be a PX4 fence (only the plan keeps "
             f"clear of them): {', '.join(fence.not_fenced)}")
    tasks = [asyncio.ensure_future(fence_vehicle(v, fence, world_origin, emit))
             for v in vehicles]
    try:
        await asyncio.gather(*tasks)
    finally:
        for task in tasks:
            task.cancel()


async def fence_vehicle(v: VehicleStatus, fence: WorldFence,
                        world_origin: frames.Geodetic | None, emit: Emit) -> None:
    """Upload `fence` to `v` in its own frame, read it back and compare (`GeofenceFailed`
    naming it otherwise, also when its home lies outside the fence: armed there, PX4 would
    act on a breach at once)."""
    placed = fence_origin(v, world_origin)
    assert placed is not None
    home, origin = placed
    outside = fence.breaches(v.placed[:2])
    if outside:
        raise GeofenceFailed(v.id, f"its home {np.round(v.placed, 3).tolist()} lies outside "
                                   f"the fence ({', '.join(outside)})")
    items = fence_items(fence, home, origin)
    for transfer in range(1, FENCE_TRANSFERS + 1):
        try:
            await send_fence(v.linked, items)
            break
        except GeofenceFailed as exc:
            if transfer == FENCE_TRANSFERS:
                raise GeofenceFailed(v.id, f"{exc.detail} (after {transfer} uploads)") from None
            emit(v.id, EventKind.GEOFENCE_RETRY, f"upload {transfer} failed ({exc.detail}); "
                                                 f"again in {FENCE_RETRY_WAIT_S:g} s")
            await asyncio.sleep(FENCE_RETRY_WAIT_S)
    emit(v.id, EventKind.GEOFENCE, f"{len(fence.shapes)} shape(s), {len(items)} items "
                                   f"uploaded and read back"
                                   + (f" (upload {transfer})" if transfer > 1 else ""))


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
