"""One vehicle: the executor's view of it (`VehicleStatus`) and the procedure on its link.

Long: the link-level procedure steps, a short coroutine each, and the `VehicleStatus` they update.

The procedure steps are link-level coroutines, so a flight (`gcs.flight.run.executor`) and a fleet
command outside a flight (`gcs.fleet.commands`) use the same code:

- `connect`: first HEARTBEAT, its autopilot chosen (`gcs.autopilot.choose`: detected, or
  the fleet file's), its streams asked for where it sends none unasked, then
  LOCAL_POSITION_NED; refuse a vehicle that is already armed; `resolve_home` places its
  LOCAL_NED origin in the world frame;
- `set_mode` / `arm`: MAV_CMD_DO_SET_MODE / MAV_CMD_COMPONENT_ARM_DISARM, retried while
  refused for now (`Autopilot.arm_retry_results`), each confirmed by COMMAND_ACK *and*
  HEARTBEAT; `set_origin`, `take_off`: what a GUIDED copter needs before it follows setpoints;
- `land` (NAV_LAND falling back to the land mode, or the land mode), `disarm`.

The executor's safe endings on these steps, which never raise, are
`gcs.flight.procedure.endings`.

What differs between autopilots is asked of the vehicle's `gcs.autopilot.Autopilot`
(`autopilot_of`), never decided here.

Every timeout counts station-running time when given the flight's `StationStalls`
(`gcs.flight.link.station`): the station's own stalls do not use it up.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from gcs import autopilot, frames
from gcs.autopilot import Autopilot, LinkLossFailsafe
from gcs.errors import (
    ArmingRefused,
    CommandError,
    GcsError,
    LinkError,
    ModeRefused,
    VehicleTimeout,
)
from gcs.fleet.fleetfile import VehicleSpec
from gcs.flight.link.interface import Link
from gcs.flight.link.station import StationStalls
from gcs.flight.link.telemetry import Telemetry
from gcs.phases import DropAction, EventKind, VehiclePhase
from gcs.wire import mavlink, result_name

__all__ = [
    "MODE_RETRY_FOR",
    "Emit",
    "VehicleStatus",
    "arm",
    "ask_origin",
    "autopilot_of",
    "connect",
    "disarm",
    "land",
    "last_text",
    "refuse_other_claimants",
    "request_message_rates",
    "resolve_home",
    "set_mode",
    "set_origin",
    "take_off",
    "wait_running",
]

#: Called with (vehicle id or None for the fleet, event kind, detail).
Emit = Callable[[str | None, EventKind, str], None]

#: How long OFFBOARD is retried while TEMPORARILY_REJECTED (the stream is not yet seen).
MODE_RETRY_FOR = 5.0
#: LOCAL_POSITION_NED's rate asked of a vehicle that streams only when asked, unless the
#: flight asks for another (FlightOptions.position_rate_hz).
POSITION_HZ = 30.0
#: Such a vehicle is asked for its streams again this often until its position comes (s).
STREAMS_ASKED_AGAIN_S = 5.0
#: Requests for GPS_GLOBAL_ORIGIN before a vehicle is taken to report none (one lost
#: datagram must not cost a flight its fence), the wait for the answer to the first (s), and
#: how much longer each next wait is: 1, 1.5, 2.25 and 3.4 s, about 8 s at most in all.
ORIGIN_TRIES = 4
ORIGIN_WAIT_S = 1.0
ORIGIN_BACKOFF = 1.5
#: SET_GPS_GLOBAL_ORIGIN sends (each followed by `ask_origin`'s requests).
SET_ORIGIN_TRIES = 2
#: The lowest takeoff (m) and how close to its height a takeoff counts as done (m).
TAKEOFF_MIN_M = 1.0
TAKEOFF_TOLERANCE_M = 0.15


@dataclass
class VehicleStatus:
    """The executor's view of one vehicle (see `FlightExecutor.snapshot`)."""

    spec: VehicleSpec
    index: int
    link: Link | None = None
    home: np.ndarray | None = None
    start_ned: np.ndarray | None = None
    goal_ned: np.ndarray | None = None
    phase: VehiclePhase = VehiclePhase.PENDING
    """Where it is in the flight (HOVERING: in its autopilot's hold mode at the end)."""
    fault: str | None = None
    fault_time: float | None = None
    armed_by_us: bool = False
    arm_sent: bool = False
    """An arming command went out (it may have armed the vehicle even if we never saw it)."""
    expect_offboard: bool = False
    """It should be in its autopilot's mode that follows setpoints (OFFBOARD, GUIDED)."""
    tracking_error: float = math.nan
    goal_error: float = math.nan
    goal_tolerance: float = math.nan
    """The tolerance its goal error is judged with (from its reported accuracy then)."""
    last_mode: str | None = None
    last_armed: bool | None = None
    dropped: DropAction | None = None
    """Taken off the plan by a switched replan (`gcs.flight.replan.replan`): ``land`` or ``hold``
    on its own motion; it is no longer judged against a goal."""
    drop_reason: str | None = None
    """Why it was dropped (the replan's reason: an operator's, or its fault)."""
    failsafe: LinkLossFailsafe = field(
        default_factory=lambda: autopilot.DEFAULT.default_failsafe)
    """What it does on its own once setpoints stop (its autopilot's defaults until read from
    it: `gcs.flight.procedure.failsafe`)."""
    failsafe_before: dict[str, float] | None = None
    """The failsafe parameters as read before the flight changed them (restored after it)."""
    failsafe_set: dict[str, float] | None = None
    """The failsafe parameters as the flight set them (what `failsafe_before` undoes)."""

    @property
    def autopilot(self) -> Autopilot:
        """The autopilot it is flown as (only once connected)."""
        return autopilot_of(self.linked)

    @property
    def id(self) -> str:
        return self.spec.id

    @property
    def placed(self) -> np.ndarray:
        """The vehicle's home in the world frame (only once connected)."""
        assert self.home is not None
        return self.home

    @property
    def linked(self) -> Link:
        """The vehicle's link (only once the links are open)."""
        assert self.link is not None
        return self.link

    def distance_ned(self, target: np.ndarray | None) -> float:
        """Reported distance to `target` (LOCAL_NED), inf when either is unknown."""
        tel = self.linked.telemetry
        if tel.position_ned is None or target is None:
            return math.inf
        return float(np.linalg.norm(np.asarray(tel.position_ned) - target))


def autopilot_of(link: Link) -> Autopilot:
    """The autopilot `link`'s vehicle is flown as (`Telemetry.flown_by`)."""
    return link.telemetry.flown_by


def last_text(link: Link) -> str:
    """The vehicle's latest STATUSTEXT, as a suffix for an error message."""
    texts = link.telemetry.statustexts
    return f" (vehicle says: {texts[-1]!r})" if texts else ""


# ==================================================================== the procedure


def _clock(stalls: StationStalls | None) -> Callable[[], float]:
    return stalls.clock if stalls is not None else time.monotonic


async def wait_running(link: Link, predicate: Callable[[Telemetry], bool],
                       timeout: float, stalls: StationStalls | None = None) -> bool:
    """`link.wait_for` with `timeout` in station-running time (see the module)."""
    return await link.wait_for(predicate, timeout, clock=_clock(stalls))


def _choose_autopilot(link: Link, spec: VehicleSpec) -> None:
    """Fly `link`'s vehicle as the autopilot the fleet file names or its HEARTBEAT reports
    (`LinkError` when neither names one the GCS flies, or they disagree)."""
    kind = autopilot.choose(spec.autopilot, link.telemetry.autopilot)
    if not isinstance(kind, Autopilot):
        raise LinkError(f"{spec.id}: {kind}")
    link.telemetry.autopilot_kind = kind


async def connect(link: Link, spec: VehicleSpec, timeout: float,
                  stalls: StationStalls | None = None, *,
                  position_hz: float = POSITION_HZ, armed_ok: bool = False) -> None:
    """Wait for the first HEARTBEAT and position, choosing the vehicle's autopilot on the way
    (asking for its streams, at `position_hz` for position, where it sends none unasked);
    refuse a vehicle whose autopilot the GCS cannot fly, and one that is already armed unless
    `armed_ok` (a fleet left hovering, taken over to land it)."""
    clock = _clock(stalls)
    deadline = clock() + timeout

    def ready(t: Telemetry) -> bool:
        """HEARTBEAT and position, or a HEARTBEAT saying not to wait for position: a
        refused autopilot, or one that streams only when asked."""
        if t.heartbeat_time is None:
            return False
        kind = autopilot.choose(spec.autopilot, t.autopilot)
        return (t.position_ned is not None or not isinstance(kind, Autopilot)
                or kind.streams_on_request)

    ok = await wait_running(link, ready, timeout, stalls)
    if ok:
        _choose_autopilot(link, spec)
        while link.telemetry.position_ned is None and clock() < deadline:
            # it streams only when asked, and may miss requests while it boots (on ArduCopter
            # SITL one vehicle of four never sent what its first requests asked for): ask
            # again until it does
            await request_message_rates(
                link, autopilot_of(link).message_rates(position_hz), stalls)
            await wait_running(link, lambda t: t.position_ned is not None,
                               min(STREAMS_ASKED_AGAIN_S, max(0.0, deadline - clock())), stalls)
        ok = link.telemetry.position_ned is not None
    if not ok:
        dropped = drop_diagnosis(link, spec)
        if dropped and link.telemetry.heartbeat_time is None:
            raise VehicleTimeout(spec.id, f"heard within {timeout:g} s on {spec.connection}, "
                                          f"but nothing it could accept: {dropped}")
        what = "HEARTBEAT" if link.telemetry.heartbeat_time is None else "LOCAL_POSITION_NED"
        endpoint = link.endpoint
        heard = link.telemetry.message_time is not None
        if endpoint.messages_received == 0 and endpoint.garbage_datagrams == 0:
            hint = ("; nothing at all arrived there: is the vehicle running and sending to "
                    "this port? (mock vehicles: fleetplan mock; PX4 SITL sends its offboard "
                    "link to 14540 + instance). " + _PARTNER_HINT)
        elif endpoint.dropped_unknown and link.telemetry.heartbeat_time is None:
            hint = (f"; {endpoint.dropped_unknown} messages arrived there from other system "
                    f"ids: is system_id {spec.system_id} right for this vehicle?")
        elif heard and link.telemetry.heartbeat_time is None and link.link_age() > timeout / 2:
            hint = (f"; its first messages arrived, then nothing for {link.link_age():.0f} s. "
                    + _PARTNER_HINT)
        else:
            hint = f"; also dropped: {dropped}" if dropped else ""
        raise VehicleTimeout(spec.id, f"no {what} within {timeout:g} s on "
                                      f"{spec.connection} (system id {spec.system_id}){hint}")
    tel = link.telemetry
    if tel.armed and not armed_ok:
        raise GcsError(f"{spec.id}: already armed; refusing to take control of a vehicle that "
                       f"someone else armed")
    refuse_other_claimants(link, spec)


#: Why a PX4 vehicle that is running may send the GCS nothing (its UDP link's partner).
_PARTNER_HINT = ("PX4 sends its replies to the first address it hears after boot, for good: "
                 "if another process spoke to it first (even with packets it rejected), "
                 "restart the vehicle with only the GCS talking to it, or fix its partner "
                 "with mavlink start -t")


#: Packets dropped from a vehicle's system id, by security counter: what they were, the
#: likely cause and what to do.
_DROP_CAUSES: dict[str, tuple[str, str]] = {
    "unsigned": ("unsigned packets",
                 "the fleet file gives this vehicle a signing_key but the key is not "
                 "provisioned on the vehicle (fleetplan keys provision --fleet FLEET.json) "
                 "or signing is off there"),
    "bad_signature": ("wrongly signed packets",
                      "signed with another key than the fleet file's signing_key: provision "
                      "this key on the vehicle (fleetplan keys provision --fleet FLEET.json "
                      "--old-key ITS_KEY), or give the fleet file the vehicle's key"),
    "replayed": ("replayed packets",
                 "signed with this key but with old timestamps: a replay, or a vehicle whose "
                 "clock went back (restart it)"),
    "other_component": ("packets from another component",
                        "not the fleet file's component_id: set it to the autopilot's"),
    "foreign_source": ("packets from another address",
                       "not the pinned peer: a second source, or the fleet file's peer is not "
                       "the vehicle's address"),
}


def drop_diagnosis(link: Link, spec: VehicleSpec) -> str:
    """What the link dropped from this vehicle's system id and the likely cause, one clause
    per reason ("" when it dropped nothing): a misconfigured link reads as what it is, not
    as a silent vehicle."""
    counts = link.telemetry.security.to_dict()
    parts = []
    for reason, (what, cause) in _DROP_CAUSES.items():
        if counts.get(reason, 0) and reason in link.dropped_from:
            address, component = link.dropped_from[reason]
            parts.append(f"{counts[reason]} {what} from {address_text(address)} (system id "
                         f"{spec.system_id}, component {component}): {cause}")
    return "; ".join(parts)


def refuse_other_claimants(link: Link, spec: VehicleSpec) -> None:
    """Two sources claiming one vehicle while it connects: refuse it and name both, so the
    first is never pinned silently (pin the real one with the fleet file's ``peer``)."""
    if link.claimants:
        others = ", ".join(address_text(a) for a in link.claimants)
        raise LinkError(f"{spec.id}: two sources claim system id {spec.system_id}: "
                        f"{address_text(link.peer_address)} and {others}; set the vehicle's `peer` "
                        f"in the fleet file to the real one")


def address_text(address: object) -> str:
    """``HOST:PORT`` for a UDP address tuple, else the address as text."""
    if isinstance(address, tuple) and len(address) == 2:
        return f"{address[0]}:{address[1]}"
    return str(address)


async def ask_origin(link: Link, stalls: StationStalls | None = None) -> bool:
    """Ask for GPS_GLOBAL_ORIGIN until the vehicle reports it, up to `ORIGIN_TRIES` times
    with a growing wait (a lossy link loses requests and answers alike); whether it did. A
    request the vehicle refuses (no ACCEPTED), or never acknowledges through all of its
    command retries, ends the asking."""
    clock = _clock(stalls)
    wait = ORIGIN_WAIT_S
    for _ in range(ORIGIN_TRIES):
        if link.telemetry.gps_origin is not None:
            return True
        try:
            result = await link.request_message(mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN,
                                                clock=clock)
        except CommandError:
            result = None  # unanswered: the origin may still come, then stop asking
        if await link.wait_for(lambda t: t.gps_origin is not None, wait, clock=clock):
            return True
        if result != mavlink.MAV_RESULT_ACCEPTED:
            break
        wait *= ORIGIN_BACKOFF
    return link.telemetry.gps_origin is not None


async def set_origin(link: Link, origin: frames.Geodetic,
                     stalls: StationStalls | None = None) -> bool:
    """Give a vehicle without an EKF origin one (SET_GPS_GLOBAL_ORIGIN, which has no answer of
    its own), then ask for it back (`ask_origin`); whether it now reports one. Its LOCAL_NED
    origin is then `origin`: the home the fleet file places it at."""
    for _ in range(SET_ORIGIN_TRIES):
        link.send(link.mav.set_gps_global_origin_encode(
            link.system_id, round(origin.lat * 1e7), round(origin.lon * 1e7),
            round(origin.alt * 1000), int(time.time() * 1e6)))
        if await ask_origin(link, stalls):
            return True
    return False


async def take_off(link: Link, height: float, *, timeout: float,
                   stalls: StationStalls | None = None, up_at: float | None = None) -> float:
    """MAV_CMD_NAV_TAKEOFF to `height` m above its LOCAL_NED origin (at least
    `TAKEOFF_MIN_M`; a copter in GUIDED leaves the ground only so), then wait until it is
    within `TAKEOFF_TOLERANCE_M` of it (or, with `up_at`, at that height on its way);
    returns the height asked for (`CommandError`, `VehicleTimeout` otherwise)."""
    clock = _clock(stalls)
    height = max(height, TAKEOFF_MIN_M)
    reached = height - TAKEOFF_TOLERANCE_M if up_at is None else min(up_at, height)
    result = await link.command(mavlink.MAV_CMD_NAV_TAKEOFF,
                                (0.0, 0.0, 0.0, math.nan, math.nan, math.nan, height),
                                clock=clock)
    if result != mavlink.MAV_RESULT_ACCEPTED:
        raise CommandError(link.vehicle_id, mavlink.MAV_CMD_NAV_TAKEOFF, result,
                           f"takeoff refused: {result_name(result)}{last_text(link)}")

    def up(t: Telemetry) -> bool:
        return t.position_ned is not None and -t.position_ned[2] >= reached

    if not await wait_running(link, up, timeout, stalls):
        raise VehicleTimeout(link.vehicle_id, f"not at {reached:g} m on its takeoff to "
                                              f"{height:g} m within {timeout:g} s"
                                              f"{last_text(link)}")
    return height


async def resolve_home(link: Link, vehicle_id: str, origin: frames.Geodetic,
                       stalls: StationStalls | None = None) -> tuple[np.ndarray, str]:
    """Home in the world frame from the vehicle's EKF origin and the fleet's world_origin;
    returns (home, the message it came from)."""
    clock = _clock(stalls)
    await ask_origin(link, stalls)
    tel = link.telemetry
    if tel.gps_origin is not None:
        return frames.geodetic_to_enu(frames.Geodetic(*tel.gps_origin), origin), \
            "GPS_GLOBAL_ORIGIN"
    with contextlib.suppress(CommandError):
        await link.request_message(mavlink.MAVLINK_MSG_ID_HOME_POSITION, clock=clock)
    if not await link.wait_for(lambda t: t.home is not None, 3.0, clock=clock):
        raise VehicleTimeout(vehicle_id, "reported neither GPS_GLOBAL_ORIGIN nor HOME_POSITION "
                                         "(needed to place it with world_origin)")
    assert tel.home is not None
    geodetic, local = tel.home
    # LOCAL_NED origin = home's position minus home's local offset
    home = (frames.geodetic_to_enu(frames.Geodetic(*geodetic), origin)
            - frames.ned_vector_to_world(local))
    return home, "HOME_POSITION"


async def set_mode(link: Link, mode: autopilot.FlightMode, *, confirm_timeout: float,
                   retry_for: float = 0.0, stalls: StationStalls | None = None) -> None:
    """DO_SET_MODE until ACCEPTED (retrying TEMPORARILY_REJECTED for `retry_for` s), then
    wait for HEARTBEAT to show the mode; `ModeRefused` otherwise."""
    clock = _clock(stalls)
    deadline = clock() + retry_for
    while True:
        result = await link.command(mavlink.MAV_CMD_DO_SET_MODE, mode.command_params,
                                    clock=clock)
        if result == mavlink.MAV_RESULT_ACCEPTED:
            if await wait_running(link, lambda t: t.mode == mode, confirm_timeout, stalls):
                return
            raise ModeRefused(link.vehicle_id, mavlink.MAV_CMD_DO_SET_MODE, result,
                              f"{mode.name} accepted but not shown in HEARTBEAT within "
                              f"{confirm_timeout:g} s")
        if result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED and clock() < deadline:
            await asyncio.sleep(0.5)
            continue
        raise ModeRefused(link.vehicle_id, mavlink.MAV_CMD_DO_SET_MODE, result,
                          f"{mode.name} refused: {result_name(result)}{last_text(link)}")


async def arm(link: Link, *, timeout: float, confirm_timeout: float,
              on_attempt: Callable[[], None] | None = None,
              on_accepted: Callable[[], None] | None = None,
              stalls: StationStalls | None = None) -> int:
    """Arm, retrying a refusal that is only for now (`Autopilot.arm_retry_results`: PX4's
    TEMPORARILY_REJECTED, ArduPilot's FAILED with a "PreArm:" text) for up to `timeout` s;
    confirmed by HEARTBEAT. Returns the number of attempts; `ArmingRefused` otherwise.
    `on_attempt` is called before each command goes out, `on_accepted` when one is
    ACCEPTED."""
    kind = autopilot_of(link)
    clock = _clock(stalls)
    deadline = clock() + timeout
    attempts = 0
    cmd = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
    while True:
        attempts += 1
        if on_attempt is not None:
            on_attempt()
        result = await link.command(cmd, (1.0,), clock=clock)
        if result == mavlink.MAV_RESULT_ACCEPTED:
            if on_accepted is not None:
                on_accepted()
            if await wait_running(link, lambda t: t.armed, confirm_timeout, stalls):
                return attempts
            raise ArmingRefused(link.vehicle_id, cmd, result,
                                f"arming accepted but HEARTBEAT not armed within "
                                f"{confirm_timeout:g} s")
        if result in kind.arm_retry_results:
            if clock() + kind.arm_retry_s < deadline:
                await asyncio.sleep(kind.arm_retry_s)
                continue
            raise ArmingRefused(link.vehicle_id, cmd, result,
                                f"arming still {result_name(result)} after {timeout:g} s"
                                f"{last_text(link)}")
        raise ArmingRefused(link.vehicle_id, cmd, result,
                            f"arming refused: {result_name(result)}{last_text(link)}")


async def land(link: Link, *, confirm_timeout: float,
               stalls: StationStalls | None = None) -> bool:
    """MAV_CMD_NAV_LAND, falling back to DO_SET_MODE to the land mode if refused, where the
    autopilot lands by command (`Autopilot.land_by_command`), else the land mode straight
    away; True when the mode was set (and confirmed); `GcsError` when neither is
    accepted."""
    kind = autopilot_of(link)
    if kind.land_by_command:
        result = await link.command(mavlink.MAV_CMD_NAV_LAND, clock=_clock(stalls))
        if result == mavlink.MAV_RESULT_ACCEPTED:
            return False
    await set_mode(link, kind.land_mode, confirm_timeout=confirm_timeout, stalls=stalls)
    return True


async def disarm(link: Link, *, force: bool = False,
                 stalls: StationStalls | None = None) -> int:
    """MAV_CMD_COMPONENT_ARM_DISARM(0); `force` adds the autopilot's magic number, which
    disarms even in the air (the vehicle falls). Returns the MAV_RESULT."""
    params = (0.0, autopilot_of(link).disarm_force_magic) if force else (0.0,)
    return await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, params,
                              clock=_clock(stalls))


async def request_message_rates(link: Link, rates: dict[int, float],
                                stalls: StationStalls | None = None) -> dict[str, str]:
    """MAV_CMD_SET_MESSAGE_INTERVAL for each message id (param2: interval in us, -1 = off);
    returns {message name: "<rate> <MAV_RESULT>"}. A refusal is reported, not raised: the
    vehicle then keeps sending at its own rate. After a request that goes unanswered the rest
    are reported "not sent" (a vehicle that ignores them would otherwise hold the connect
    phase for minutes). PX4 keeps the rates it was given until it reboots."""
    out: dict[str, str] = {}
    unanswered = False
    for message_id, hz in rates.items():
        interval = -1.0 if hz <= 0 else 1e6 / hz
        name = mavlink.mavlink_map[message_id].msgname if message_id in mavlink.mavlink_map \
            else str(message_id)
        if unanswered:
            out[name] = f"{'off' if hz <= 0 else f'{hz:g} Hz'} not sent"
            continue
        try:
            result = result_name(await link.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                                                    (float(message_id), interval),
                                                    clock=_clock(stalls)))
        except GcsError as exc:
            result = f"failed ({exc})"
            unanswered = True
        out[name] = f"{'off' if hz <= 0 else f'{hz:g} Hz'} {result}"
    return out
