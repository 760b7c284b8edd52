"""A fake `VehicleLink`: the few things the monitor and the vehicle procedure use, no sockets.

`FakeLink` answers commands from a small PX4-like rule set (modes and arming take effect at
once, NAV_LAND lands and disarms) and lets a test set telemetry directly.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np

from gcs.autopilot import px4
from gcs.fleet.fleetfile import VehicleSpec
from gcs.flight.link.telemetry import Telemetry
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.safety.monitor import Watched
from gcs.wire import mavlink

__all__ = ["FakeLink", "Findings", "fake_link", "fake_vehicle"]


class FakeLink:
    """What the executor's helpers use from a `VehicleLink`, in memory."""

    def __init__(self, vehicle_id: str, *, answer: bool = True) -> None:
        self.vehicle_id = vehicle_id
        self.component_id = 1
        self.telemetry = Telemetry(autopilot=mavlink.MAV_AUTOPILOT_PX4, mode=px4.OFFBOARD,
                                   position_ned=(0.0, 0.0, -1.5), velocity_ned=(0.0, 0.0, 0.0))
        self.answer = answer
        """False: commands go unanswered (`GcsError` like a real link's retries)."""
        self.commands: list[int] = []
        self.endpoint = SimpleNamespace(garbage_datagrams=0)
        self.dropped_from: dict[str, tuple[Any, int]] = {}
        self.alive()

    def alive(self, now: float | None = None) -> None:
        """A HEARTBEAT and a position arrive now."""
        now = time.monotonic() if now is None else now
        tel = self.telemetry
        tel.message_time = tel.heartbeat_time = tel.position_time = now

    async def command(self, command: int, params: Any = (), clock: Any = None) -> int:
        from gcs.errors import CommandError

        self.commands.append(command)
        await asyncio.sleep(0)
        if not self.answer:
            raise CommandError(self.vehicle_id, command, None,
                               f"no COMMAND_ACK for command {command}")
        tel = self.telemetry
        if command == mavlink.MAV_CMD_NAV_LAND:
            tel.mode, tel.armed = px4.LAND, False
            tel.landed_state = mavlink.MAV_LANDED_STATE_ON_GROUND
        elif command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            tel.armed = bool(params and params[0])
        elif command == mavlink.MAV_CMD_DO_SET_MODE:
            tel.mode = next(m for m in (px4.OFFBOARD, px4.HOLD, px4.LAND, px4.POSITION)
                            if m.command_params == tuple(params))
        self.alive()
        return mavlink.MAV_RESULT_ACCEPTED

    async def request_message(self, message_id: int, timeout: float = 1.0, *,
                              clock: Any = None) -> int:
        """MAV_CMD_REQUEST_MESSAGE, answered like any command (nothing is sent back)."""
        return await self.command(mavlink.MAV_CMD_REQUEST_MESSAGE, (float(message_id),))

    async def wait_for(self, predicate: Callable[[Telemetry], bool], timeout: float,
                       clock: Any = None) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate(self.telemetry):
            if time.monotonic() >= deadline:
                return False
            await asyncio.sleep(0.01)
        return True

    def pack_setpoint(self, setpoint: Any, boot_ms: int) -> bytes:
        """Nothing to encode: the streamer's listeners see the setpoints."""
        return b""

    def send_packed(self, buf: bytes) -> None:
        """Nowhere to send."""

    def link_age(self, now: float | None = None) -> float:
        t = self.telemetry.message_time
        return float("inf") if t is None else (now or time.monotonic()) - t

    def heartbeat_age(self, now: float | None = None) -> float:
        t = self.telemetry.heartbeat_time
        return float("inf") if t is None else (now or time.monotonic()) - t


def fake_link(v: VehicleStatus) -> FakeLink:
    """The `FakeLink` of a vehicle made by `fake_vehicle`."""
    assert isinstance(v.link, FakeLink)
    return v.link


def fake_vehicle(index: int, *, home: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 **link_kw: Any) -> VehicleStatus:
    """A `VehicleStatus` on a `FakeLink`, meant to be in OFFBOARD (as while flying)."""
    vid = f"uav{index + 1}"
    spec = VehicleSpec(id=vid, connection=f"udpin:127.0.0.1:{40000 + index}",
                       system_id=index + 1, component_id=1, home=np.asarray(home, dtype=float))
    v = VehicleStatus(spec, index)
    v.link = FakeLink(vid, **link_kw)  # type: ignore[assignment]
    v.home = np.asarray(home, dtype=float)
    v.expect_offboard = True
    return v


class Findings(Watched):
    """A flight watched by a monitor in a test: a fixed flight time, the positions predicted
    for unheard vehicles (by id), and what the monitor found, in order."""

    def __init__(self, flight_time: float | None = None,
                 predicted: dict[str, np.ndarray] | None = None,
                 faults: list[tuple[str, str, float]] | None = None) -> None:
        self.time = flight_time
        self.guesses = predicted or {}
        self.faults = faults if faults is not None else []
        """(vehicle id, fault kind, GCS clock when found)."""
        self.separations: list[tuple[float, float, str]] = []
        """(closest, alarm, the pair named)."""
        self.silent: list[str] = []
        self.heard: list[str] = []

    def flight_time(self) -> float | None:
        return self.time

    def predicted(self, v: VehicleStatus, t: float) -> np.ndarray | None:
        return self.guesses.get(v.id)

    def on_fault(self, v: VehicleStatus, kind: str, detail: str) -> None:
        self.faults.append((v.id, kind, time.monotonic()))

    def on_separation(self, closest: float, alarm: float, between: str) -> None:
        self.separations.append((closest, alarm, between))

    def on_silent(self, v: VehicleStatus, silent: float) -> None:
        self.silent.append(v.id)

    def on_heard(self, v: VehicleStatus) -> None:
        self.heard.append(v.id)
