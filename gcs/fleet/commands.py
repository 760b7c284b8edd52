"""Fleet commands outside a flight: hold, land, return to launch, disarm, flight termination.

What an operator needs when no flight is running, above all to land a fleet left hovering
(an abort with ``hold``, an ``at_end: hold`` flight, a GCS restart). Each command goes to every
chosen vehicle at once, is acknowledged (COMMAND_ACK) and then confirmed from telemetry before
it counts as done:

========== ====================================================== ===========================
command    sent                                                   confirmed by
========== ====================================================== ===========================
hold       DO_SET_MODE AUTO.LOITER                                HEARTBEAT mode
land       NAV_LAND (else DO_SET_MODE AUTO.LAND)                  HEARTBEAT mode (or disarmed)
rtl        DO_SET_MODE AUTO.RTL                                   HEARTBEAT mode
disarm     COMPONENT_ARM_DISARM 0 (+ PX4's force value if forced) HEARTBEAT disarmed
terminate  DO_FLIGHTTERMINATION 1                                 HEARTBEAT disarmed or
                                                                  MAV_STATE_FLIGHT_TERMINATION
========== ====================================================== ===========================

Safety rules, checked before anything is sent (`check_command`): ``disarm`` is refused for a
vehicle that is (or may be) in the air unless ``force`` is set (its motors stop and it falls);
``terminate`` needs ``confirm``. A disarmed vehicle needs no land and no disarm (reported done,
nothing sent). A vehicle that never sent a HEARTBEAT is reported as such, not commanded.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

from gcs.errors import GcsError, InvalidRequest, StateConflict
from gcs.flight.link.link import VehicleLink
from gcs.flight.procedure import vehicle
from gcs.phases import FLEET_COMMANDS
from gcs.wire import mavlink, result_name

__all__ = ["CommandOutcome", "check_command", "fleet_command", "run_command"]

#: How long a command's effect may take to show in HEARTBEAT (PX4 sends it at 1 Hz).
CONFIRM_TIMEOUT_S = 5.0

#: Fleet commands that are a mode switch, by the `Autopilot` attribute naming the mode.
_MODES = {"hold": "hold_mode", "rtl": "rtl_mode"}


@dataclass(frozen=True)
class CommandOutcome:
    """What one vehicle did with a command."""

    vehicle: str
    command: str
    done: bool
    """Acknowledged and its effect seen in telemetry."""
    detail: str
    mode: str | None
    """HEARTBEAT mode afterwards (None before the first HEARTBEAT)."""
    armed: bool | None

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def _in_air(link: VehicleLink) -> bool:
    """Armed and not known to be on the ground (EXTENDED_SYS_STATE): may be flying."""
    tel = link.telemetry
    return tel.armed and tel.landed_state != mavlink.MAV_LANDED_STATE_ON_GROUND


def check_command(command: str, links: Mapping[str, VehicleLink], *, force: bool = False,
                  confirm: bool = False) -> None:
    """Refuse an unsafe or malformed command before anything is sent: `InvalidRequest` for an
    unknown command or a terminate without `confirm`; `StateConflict` for a disarm of a
    vehicle in the air without `force`."""
    if command not in FLEET_COMMANDS:
        raise InvalidRequest("command", f"must be one of {', '.join(FLEET_COMMANDS)}, "
                                        f"got {command!r}")
    if command == "terminate" and not confirm:
        raise InvalidRequest("confirm", "terminate stops the motors in flight (the vehicles "
                                        "fall): send confirm: true to do it")
    if command == "disarm" and not force:
        flying = [vid for vid, link in links.items() if _in_air(link)]
        if flying:
            raise StateConflict("force", f"refusing to disarm {', '.join(flying)} in the air "
                                         "(it would fall): land it, or send force: true")


def _outcome(link: VehicleLink, command: str, done: bool, detail: str) -> CommandOutcome:
    tel = link.telemetry
    known = tel.heartbeat_time is not None
    return CommandOutcome(link.vehicle_id, command, done, detail,
                          tel.mode.name if known and tel.mode is not None else None,
                          bool(tel.armed) if known else None)


async def run_command(link: VehicleLink, command: str, *, force: bool = False,
                      confirm_timeout: float = CONFIRM_TIMEOUT_S) -> CommandOutcome:
    """Send `command` to one vehicle and confirm its effect; never raises for a vehicle's
    refusal or silence (the outcome says so). Call `check_command` first."""
    tel = link.telemetry
    if tel.heartbeat_time is None:
        return _outcome(link, command, False, "no HEARTBEAT from this vehicle yet: is it on "
                                              "and connected?")
    try:
        kind = vehicle.autopilot_of(link)
        if command in _MODES:
            mode = getattr(kind, _MODES[command])
            await vehicle.set_mode(link, mode, confirm_timeout=confirm_timeout)
            return _outcome(link, command, True, f"{mode.name} confirmed")
        if command == "land":
            if not tel.armed:
                return _outcome(link, command, True, "already disarmed: nothing to land")
            await vehicle.land(link, confirm_timeout=confirm_timeout)
            landing = kind.land_mode
            ok = await link.wait_for(lambda t: t.mode == landing or not t.armed,
                                     confirm_timeout)
            return _outcome(link, command, ok, f"landing ({landing.name} confirmed)" if ok else
                            f"land accepted but {landing.name} not shown within "
                            f"{confirm_timeout:g} s")
        if command == "disarm":
            if not tel.armed:
                return _outcome(link, command, True, "already disarmed")
            result = await vehicle.disarm(link, force=force)
            if result != mavlink.MAV_RESULT_ACCEPTED:
                return _outcome(link, command, False, f"disarm refused: {result_name(result)}"
                                                      f"{vehicle.last_text(link)}")
            ok = await link.wait_for(lambda t: not t.armed, confirm_timeout)
            return _outcome(link, command, ok, ("disarmed" + (" (forced)" if force else ""))
                            if ok else f"disarm accepted but still armed after "
                                       f"{confirm_timeout:g} s")
        if command == "terminate":
            result = await link.command(mavlink.MAV_CMD_DO_FLIGHTTERMINATION, (1.0,))
            if result != mavlink.MAV_RESULT_ACCEPTED:
                return _outcome(link, command, False, f"termination refused: "
                                                      f"{result_name(result)}")
            ok = await link.wait_for(
                lambda t: not t.armed
                or t.system_status == mavlink.MAV_STATE_FLIGHT_TERMINATION, confirm_timeout)
            return _outcome(link, command, ok, "terminated: motors off" if ok else
                            "termination accepted but not shown in HEARTBEAT")
    except GcsError as exc:
        return _outcome(link, command, False, str(exc))
    raise ValueError(f"unknown fleet command {command!r}")


async def fleet_command(links: Mapping[str, VehicleLink], command: str,
                        vehicles: Sequence[str] | None = None, *, force: bool = False,
                        confirm: bool = False,
                        confirm_timeout: float = CONFIRM_TIMEOUT_S) -> list[CommandOutcome]:
    """`command` to `vehicles` (default: all of `links`) at once; one outcome each, in order.
    `InvalidRequest` / `StateConflict` (nothing sent) as `check_command` says."""
    chosen = list(links) if vehicles is None else list(dict.fromkeys(vehicles))
    unknown = [vid for vid in chosen if vid not in links]
    if unknown:
        raise InvalidRequest("vehicles", f"no vehicle {', '.join(map(repr, unknown))} in the "
                                         f"fleet (it has {', '.join(map(repr, links))})")
    if not chosen:
        raise InvalidRequest("vehicles", "must name at least one vehicle")
    targets = {vid: links[vid] for vid in chosen}
    check_command(command, targets, force=force, confirm=confirm)
    return list(await asyncio.gather(*(
        run_command(link, command, force=force, confirm_timeout=confirm_timeout)
        for link in targets.values())))
