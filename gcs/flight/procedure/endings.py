"""The executor's safe endings of one vehicle, on the procedure's steps
(`gcs.flight.procedure.vehicle`): `land_vehicle`, `hold_vehicle`, `secure` (whatever state it
is in, leave it safe) and `wait_disarmed`. None of them raises: a failure is an event, and
the vehicle's own failsafe is the fallback. Each takes the flight it runs in as one
`FlightContext` (its options, events, stalls, and how a vehicle's setpoints stop).
"""

from __future__ import annotations

import asyncio
import time

from gcs.errors import GcsError
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus, disarm, land, set_mode
from gcs.phases import EventKind, VehiclePhase
from gcs.wire import mavlink, result_name

__all__ = ["hold_vehicle", "land_vehicle", "secure", "wait_disarmed"]

#: How often `wait_disarmed` looks at the landing vehicles (s).
POLL_PERIOD = 0.05


async def land_vehicle(v: VehicleStatus, context: FlightContext) -> None:
    """Send `v` down; its setpoints stop either way (its own failsafe is then what acts if
    the command never arrived)."""
    v.phase = VehiclePhase.LANDING
    v.expect_offboard = False
    try:
        if await land(v.linked, confirm_timeout=context.options.heartbeat_timeout,
                      stalls=context.stalls):
            context.emit(v.id, EventKind.MODE, f"{v.autopilot.land_mode.name} confirmed")
        context.emit(v.id, EventKind.LAND, "landing")
    except GcsError as exc:
        context.emit(v.id, EventKind.LAND_FAILED, f"{exc}; setpoints stopped, {_on_its_own(v)}")
    finally:
        context.stop_stream(v.id)


async def hold_vehicle(v: VehicleStatus, context: FlightContext) -> None:
    """Switch `v` to its autopilot's hold mode where it is (PX4 Hold, ArduPilot BRAKE); its
    setpoints stop either way."""
    v.expect_offboard = False
    try:
        kind = v.autopilot
        await set_mode(v.linked, kind.hold_mode, confirm_timeout=context.options.heartbeat_timeout,
                       stalls=context.stalls)
        context.emit(v.id, EventKind.MODE, f"{kind.hold_mode.name} confirmed")
        context.emit(v.id, EventKind.HOLD, f"holding ({kind.hold_words})")
    except GcsError as exc:
        context.emit(v.id, EventKind.HOLD_FAILED,
                     f"{exc}; setpoints stopped, {_on_its_own(v, True)}")
    finally:
        context.stop_stream(v.id)


def _on_its_own(v: VehicleStatus, hold: bool = False) -> str:
    """What `v` does on its own once its setpoints stop, as the end of a failure's event."""
    if v.link is None:
        return "its own failsafe takes over"
    return v.link.telemetry.flown_by.left_alone[1 if hold else 0]


async def secure(v: VehicleStatus, action: str, context: FlightContext) -> None:
    """Leave `v` safe: disarmed on the ground, landing, or (action hold) in Hold."""
    if v.link is None:
        return
    tel = v.link.telemetry
    if not tel.armed and not v.arm_sent:
        context.stop_stream(v.id)
        v.expect_offboard = False
        if v.phase != VehiclePhase.LANDED:
            v.phase = VehiclePhase.STOPPED
        return
    on_ground = v.phase == VehiclePhase.ARMING or (
        tel.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND)
    if on_ground:  # armed, or an arming command may have armed it: disarm
        v.expect_offboard = False
        try:
            result = await disarm(v.link, stalls=context.stalls)
            context.emit(v.id, EventKind.DISARM, f"on the ground: {result_name(result)}")
        except GcsError as exc:
            result = None
            context.emit(v.id, EventKind.DISARM_FAILED, str(exc))
        if result == mavlink.MAV_RESULT_ACCEPTED:
            context.stop_stream(v.id)
            v.phase = VehiclePhase.STOPPED
            return
        # refused (it has taken off after all) or unanswered: land it
    if action == "hold":
        await hold_vehicle(v, context)
        v.phase = VehiclePhase.HOVERING
    else:
        await land_vehicle(v, context)


def _landed_name(state: int | None) -> str:
    """EXTENDED_SYS_STATE's landed state in words."""
    return {mavlink.MAV_LANDED_STATE_ON_GROUND: "on the ground",
            mavlink.MAV_LANDED_STATE_IN_AIR: "in the air",
            mavlink.MAV_LANDED_STATE_LANDING: "landing",
            mavlink.MAV_LANDED_STATE_TAKEOFF: "taking off"}.get(state or 0, "landed state unknown")


async def wait_disarmed(vehicles: list[VehicleStatus], context: FlightContext) -> None:
    """Wait (up to `land_timeout`) for landing vehicles to disarm, reporting each outcome
    (nothing to wait for when `vehicles` is empty)."""
    options, emit, stalls = context.options, context.emit, context.stalls
    deadline = context.clock() + options.land_timeout
    pending = [v for v in vehicles if v.link is not None]
    while pending and context.clock() < deadline:
        still = []
        now = time.monotonic()
        for v in pending:
            link = v.linked
            tel = link.telemetry
            silent = stalls.age(tel.message_time, now)
            if silent > options.link_timeout:
                if not tel.armed and tel.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
                    v.phase = VehiclePhase.LANDED_LINK_LOST
                    emit(v.id, EventKind.DISARM_UNCONFIRMED,
                         f"link lost: landed and disarmed when last heard {silent:.1f} s ago, "
                         f"out of reach since")
                else:
                    emit(v.id, EventKind.DISARM_UNCONFIRMED,
                         f"link lost: {'armed' if tel.armed else 'disarmed'} and "
                         f"{_landed_name(tel.landed_state)} when last heard {silent:.1f} s "
                         f"ago: cannot confirm that it landed and disarmed")
                continue
            stale = stalls.age(tel.heartbeat_time, now) > options.heartbeat_timeout
            if stale and tel.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
                v.phase = VehiclePhase.LANDED
                emit(v.id, EventKind.DISARM_UNCONFIRMED,
                     "on the ground (EXTENDED_SYS_STATE), but no HEARTBEAT to "
                     "confirm that it disarmed")
                continue
            if not tel.armed and not stale:
                if v.phase == VehiclePhase.LANDING:
                    v.phase = VehiclePhase.LANDED
                    emit(v.id, EventKind.LANDED, "landed and disarmed")
            else:
                still.append(v)
        pending = still
        await asyncio.sleep(POLL_PERIOD)
    for v in pending:
        emit(v.id, EventKind.NOT_DISARMED, f"not disarmed within {options.land_timeout:g} s")
