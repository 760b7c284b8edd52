"""One vehicle's way into the air in a flight: connect, home, the pre-flight gate, message
rates, its geofence, then its autopilot's boarding steps to the climb to its start.

The executor (`gcs.flight.run.executor`) runs `connect_vehicle` for every vehicle, then
`fence_fleet` (`fence_vehicle` for every vehicle), `set_failsafes`, then `prepare_vehicle` for
every vehicle, concurrently; the commands themselves are the
primitives of `gcs.flight.procedure.vehicle`. Each step takes the flight's `FlightContext`
(`gcs.flight.procedure.context`): its options, its events, and the `StationStalls` clock every
deadline is on.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence

import numpy as np

from gcs import frames
from gcs.autopilot import Autopilot
from gcs.errors import GeofenceFailed, PreflightFailed
from gcs.flight.link.setpoints import hold_track, transfer_track
from gcs.flight.procedure import vehicle
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.failsafe import (
    column_conflicts,
    failsafe_record,
    layer_delays,
    set_failsafe,
)
from gcs.flight.procedure.fence_upload import enable_fence, send_fence
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.flight.run.record import FlightRecorder
from gcs.flight.safety.health import PreflightThresholds, preflight_problems
from gcs.flight.safety.margin import required_separation
from gcs.flight.timeline.stream import Streamer
from gcs.geofence import WorldFence, fence_items
from gcs.phases import EventKind, VehiclePhase
from planner import Plan

__all__ = ["FENCE_RETRY_MARGIN_S", "FENCE_TRANSFERS", "arm_vehicle", "connect_vehicle",
           "fence_fleet", "fence_origin", "fence_retry_wait", "fence_vehicle", "preflight",
           "prepare_vehicle", "set_failsafes"]

#: Whole uploads (with read-back) of a vehicle's fence before the flight is refused, and the
#: wait before each next (s): every message of one upload is already resent 5 times, so a
#: next upload is for a link that lost a run of them; it waits until the vehicle has given
#: the failed transfer up (PX4 refuses another meanwhile): its autopilot's
#: `mission_protocol_timeout_s` and this much more.
FENCE_TRANSFERS = 3
FENCE_RETRY_MARGIN_S = 0.5


async def connect_vehicle(v: VehicleStatus, context: FlightContext,
                          world_origin: frames.Geodetic | None, recorder: FlightRecorder, *,
                          take_over: bool = False) -> None:
    """First HEARTBEAT and position, home in the world frame (from `world_origin` when the
    fleet file gives none), the pre-flight gate, and the message rates when asked for
    (take_over: an armed vehicle is taken, not refused)."""
    options, emit, stalls = context.options, context.emit, context.stalls
    link = v.linked
    await vehicle.connect(link, v.spec, options.connect_timeout, stalls,
                          position_hz=options.position_rate_hz, armed_ok=take_over)
    v.failsafe = v.autopilot.default_failsafe
    recorder.vehicles[v.id].autopilot = v.autopilot.key
    if v.home is None:
        assert world_origin is not None
        v.home, source = await vehicle.resolve_home(link, v.id, world_origin, stalls)
        recorder.vehicles[v.id].home = v.home.tolist()
        emit(v.id, EventKind.HOME, f"from {source}: {np.round(v.home, 3).tolist()}")
    await preflight(v, context)
    if options.message_rates == "request":
        answers = await vehicle.request_message_rates(
            link, v.autopilot.message_rates(options.position_rate_hz), stalls)
        emit(v.id, EventKind.MESSAGE_RATES, ", ".join(f"{k} {a}" for k, a in answers.items()))
    vehicle.refuse_other_claimants(link, v.spec)  # over the whole connect, not its start
    v.phase = VehiclePhase.CONNECTED
    mode = link.telemetry.mode
    emit(v.id, EventKind.CONNECTED, f"mode {mode.name if mode else '?'}, home "
                                    f"{np.round(v.home, 3).tolist()}")


async def preflight(v: VehicleStatus, context: FlightContext) -> None:
    """The pre-flight gate (`gcs.flight.safety.health`): wait up to `preflight_wait` for the
    vehicle to be fit; then refuse it (`PreflightFailed`), or with `preflight: override`
    record what was overridden and carry on."""
    options = context.options
    limits = PreflightThresholds(min_battery_pct=options.min_battery_pct)
    link = v.linked
    if options.preflight == "check":
        await vehicle.wait_running(link, lambda t: not preflight_problems(t, limits),
                                   options.preflight_wait, context.stalls)
    problems = preflight_problems(link.telemetry, limits)
    if not problems:
        return
    if options.preflight == "check":
        raise PreflightFailed(v.id, problems)
    context.emit(v.id, EventKind.PREFLIGHT_OVERRIDE, "; ".join(problems))


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


def fence_retry_wait(kind: Autopilot) -> float:
    """The wait before a fence upload is tried again (s): until a vehicle of `kind` has given
    the failed transfer up."""
    return kind.mission_protocol_timeout_s + FENCE_RETRY_MARGIN_S


async def fence_fleet(vehicles: Sequence[VehicleStatus], fence: WorldFence,
                      context: FlightContext, world_origin: frames.Geodetic | None) -> None:
    """The fleet option `geofence` applied: upload `fence` to every vehicle, or say why not
    (`GeofenceFailed` when an explicit upload has no origin or fails)."""
    options, emit = context.options, context.emit
    if options.geofence == "skip":
        emit(None, EventKind.GEOFENCE_SKIPPED, "fleet option geofence: skip")
        return
    await asyncio.gather(*(vehicle.ask_origin(v.linked, context.stalls) for v in vehicles))
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
    retry_wait = fence_retry_wait(v.autopilot)
    for transfer in range(1, FENCE_TRANSFERS + 1):
        try:
            await send_fence(v.linked, items)
            break
        except GeofenceFailed as exc:
            if transfer == FENCE_TRANSFERS:
                raise GeofenceFailed(v.id, f"{exc.detail} (after {transfer} uploads)") from None
            emit(v.id, EventKind.GEOFENCE_RETRY, f"upload {transfer} failed ({exc.detail}); "
                                                 f"again in {retry_wait:g} s")
            await asyncio.sleep(retry_wait)
    enabled = await enable_fence(v.linked, v.autopilot)
    emit(v.id, EventKind.GEOFENCE, f"{len(fence.shapes)} shape(s), {len(items)} items "
                                   f"uploaded and read back"
                                   + (f" (upload {transfer})" if transfer > 1 else "")
                                   + (f", {enabled}" if enabled else ""))


async def prepare_vehicle(v: VehicleStatus, streamer: Streamer, context: FlightContext,
                          yaw_ned: float, world_origin: frames.Geodetic | None = None, *,
                          on_ground: bool = False) -> None:
    """Take `v` from disarmed on the ground to streaming the climb to its start
    (`v.start_ned`) by its autopilot's boarding steps (`Autopilot.boarding`: PX4 prestreams,
    switches to OFFBOARD, arms and climbs on setpoints; ArduPilot gets an EKF origin,
    switches to GUIDED, arms, takes off to the start's height, then follows setpoints).
    `on_ground`: its plan starts where it stands and takes off by itself; only the steps up
    to the mode that follows setpoints are taken (`Autopilot.ground_boarding`: arming and
    the takeoff are `gcs.flight.run.ground`'s, on the flight clock)."""
    options, emit, stalls = context.options, context.emit, context.stalls
    link = v.linked
    kind = v.autopilot
    here = np.asarray(link.telemetry.position_ned, dtype=float)
    for step in kind.ground_boarding if on_ground else kind.boarding:
        if step == "prestream":
            streamer.assign(v.id, link, hold_track(here, yaw_ned, options.rate_hz))
            await asyncio.sleep(options.prestream)
        elif step == "origin":
            await _ensure_origin(v, world_origin, context)
        elif step == "follow":
            v.phase = VehiclePhase.ARMING
            await vehicle.set_mode(link, kind.follow_mode,
                                   confirm_timeout=options.heartbeat_timeout,
                                   retry_for=vehicle.MODE_RETRY_FOR, stalls=stalls)
            emit(v.id, EventKind.MODE, f"{kind.follow_mode.name} confirmed")
            v.expect_offboard = True
        elif step == "arm":
            await arm_vehicle(v, context)
        elif step == "takeoff":
            assert v.start_ned is not None
            height = await vehicle.take_off(link, -float(v.start_ned[2]),
                                            timeout=options.gather_timeout, stalls=stalls)
            emit(v.id, EventKind.CLIMB, f"took off to {height:.2f} m (NAV_TAKEOFF)")
            here = np.asarray(link.telemetry.position_ned, dtype=float)
        elif step == "climb":
            assert v.start_ned is not None
            track = transfer_track(here, v.start_ned, options.climb_speed, yaw_ned,
                                   options.rate_hz)
            streamer.assign(v.id, link, track)
            v.phase = VehiclePhase.CLIMBING
            emit(v.id, EventKind.CLIMB, f"to start, {track.duration:.1f} s")
        else:
            raise ValueError(f"unknown boarding step {step!r}")


async def arm_vehicle(v: VehicleStatus, context: FlightContext,
                      timeout: float | None = None) -> None:
    """Arm `v` (retried for `timeout`, the fleet's `arm_timeout` by default), recording that
    an arming command went out and that one was accepted."""

    def attempt() -> None:
        v.arm_sent = True

    def accepted() -> None:
        v.armed_by_us = True

    options = context.options
    v.phase = VehiclePhase.ARMING
    attempts = await vehicle.arm(v.linked, timeout=options.arm_timeout if timeout is None
                                 else timeout,
                                 confirm_timeout=options.heartbeat_timeout,
                                 on_attempt=attempt, on_accepted=accepted,
                                 stalls=context.stalls)
    context.emit(v.id, EventKind.ARMED, f"after {attempts} attempt(s)")


async def _ensure_origin(v: VehicleStatus, world_origin: frames.Geodetic | None,
                         context: FlightContext) -> None:
    """`v` has an EKF origin (GPS_GLOBAL_ORIGIN), or gets one at its home placed by the
    fleet's `world_origin` (SET_GPS_GLOBAL_ORIGIN); `PreflightFailed` when neither."""
    link, stalls = v.linked, context.stalls
    if await vehicle.ask_origin(link, stalls):
        return
    if world_origin is None:
        raise PreflightFailed(v.id, ["it reports no EKF origin (GPS_GLOBAL_ORIGIN) and the "
                                     "fleet file has no world_origin to set one from: give "
                                     "world_origin"])
    geodetic = frames.enu_to_geodetic(v.placed, world_origin)
    if not await vehicle.set_origin(link, geodetic, stalls):
        raise PreflightFailed(v.id, ["its EKF origin was set (SET_GPS_GLOBAL_ORIGIN) but it "
                                     "does not report one (GPS_GLOBAL_ORIGIN)"])
    context.emit(v.id, EventKind.HOME, f"EKF origin set at its home: lat {geodetic.lat:.7f}, "
                                       f"lon {geodetic.lon:.7f}, alt {geodetic.alt:.2f} m")


async def set_failsafes(vehicles: Sequence[VehicleStatus], plan: Plan, context: FlightContext,
                        recorder: FlightRecorder) -> None:
    """Before arming, each vehicle's own link-loss failsafe is set from the plan (Hold
    where its column meets another's, else Land by altitude layer, lowest first:
    `gcs.flight.procedure.failsafe`), told per vehicle and recorded; a vehicle that does
    not take it refuses the flight (`FailsafeNotSet`) unless the fleet option
    `failsafe` is `try`."""
    delays = layer_delays(plan, context.options.land_speed)
    conflicts = column_conflicts(plan, required_separation(plan.scenario))

    def why(vid: str) -> str:
        c = conflicts.get(vid)
        if c is None:
            return "its column keeps R from every other's"
        where = "onto" if c.above else "under"
        return (f"its column comes {c.gap:.2f} m from {c.other}'s at t={c.t:.1f} s: it "
                f"hovers where the plan keeps R instead of landing {where} it")

    await asyncio.gather(*(set_failsafe(v, delays[v.index], v.id in conflicts, context,
                                        why=why(v.id))
                           for v in vehicles))
    for v in vehicles:
        recorder.vehicles[v.id].failsafe = {
            **failsafe_record(v.failsafe), "set": v.failsafe_before is not None,
            "why": why(v.id)}
    hovering = [v.id for v in vehicles if v.failsafe.effective == "Hold"]
    if hovering:
        context.emit(None, EventKind.FAILSAFE, (
            f"if the station is lost, {', '.join(hovering)} hover (their columns meet "
            f"others'); land them by plan from a station: fleetplan fleet land --plan "
            f"PLAN.json --fleet FLEET.json"))
