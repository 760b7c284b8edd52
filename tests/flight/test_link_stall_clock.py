"""A station stall longer than one try of `VehicleLink.command` (or a `wait_for` timeout) does
not use that try up when the link is given the flight's `StationStalls.clock`, on a real link
against a small responder on loopback.

The stall is real (the test blocks the event loop) and noted the way the monitor and the
streamer note theirs; the answer goes out only after the loop ran again, so a wall-time
timeout would have expired by then (`test_..._without_the_stall_clock` shows it does)."""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Callable
from typing import Any

import pytest

from gcs.autopilot import px4
from gcs.errors import CommandError
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.station import StationStalls
from gcs.wire import GCS_SYSTEM_ID, mavlink, parse_datagram
from tests.flight.support import free_port_block

pytestmark = pytest.mark.timeout(30)

ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
TRY_S = 0.5
STALL_S = 1.0


class Responder:
    """A UDP socket speaking as vehicle 1: heartbeats and COMMAND_ACKs on demand."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)

    def heartbeat(self, armed: bool = False) -> None:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        self._send(self.mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR,
                                             mavlink.MAV_AUTOPILOT_PX4, base,
                                             px4.HOLD.custom_mode, mavlink.MAV_STATE_STANDBY))

    def ack(self, command: int) -> None:
        self._send(self.mav.command_ack_encode(command, mavlink.MAV_RESULT_ACCEPTED, 0, 0,
                                               GCS_SYSTEM_ID, 190))

    def _send(self, msg: Any) -> None:
        self.sock.sendto(msg.pack(self.mav), ("127.0.0.1", self.port))

    def commands(self) -> list[int]:
        """COMMAND_LONG ids received since the last call."""
        out: list[int] = []
        while True:
            try:
                data = self.sock.recv(4096)
            except BlockingIOError:
                return out
            out.extend(m.command for m in parse_datagram(data).messages
                       if m.get_type() == "COMMAND_LONG")


async def _until(condition: Callable[[], Any], bound: float = 10.0) -> None:
    deadline = time.monotonic() + bound  # bound
    while not condition():
        assert time.monotonic() < deadline, "what the packets sent must cause never happened"
        await asyncio.sleep(0.001)


def _stall(stalls: StationStalls) -> None:
    """Block the event loop for `STALL_S` (a stalled station) and note it."""
    start = time.monotonic()
    time.sleep(STALL_S)
    stalls.note(start, time.monotonic())


async def _linked(hub: LinkHub, vehicle: Responder) -> VehicleLink:
    link = await hub.add("uav1", f"udpin:127.0.0.1:{vehicle.port}", 1)
    vehicle.heartbeat()  # pins the peer: commands go to it
    await _until(lambda: link.telemetry.heartbeat_time is not None)
    return link


async def _command_across_a_stall(stalls: StationStalls | None) -> int:
    vehicle = Responder(free_port_block(1))
    try:
        async with LinkHub() as hub:
            link = await _linked(hub, vehicle)
            clock = stalls.clock if stalls is not None else None
            task = asyncio.create_task(link.command(ARM, (1.0,), timeout=TRY_S, retries=0,
                                                    clock=clock))
            sent: list[int] = []

            def arm_sent() -> bool:
                sent.extend(vehicle.commands())
                return ARM in sent

            await _until(arm_sent)
            _stall(stalls if stalls is not None else StationStalls())
            # let the loop run the try's expired wall-time timer before the answer goes out
            await asyncio.sleep(0.1)
            if not task.done():
                vehicle.ack(ARM)
            return await task
    finally:
        vehicle.sock.close()


def test_a_command_answered_after_a_noted_stall_longer_than_a_try_succeeds() -> None:
    result = asyncio.run(_command_across_a_stall(StationStalls()))
    assert result == mavlink.MAV_RESULT_ACCEPTED


def test_the_same_command_runs_out_of_tries_without_the_stall_clock() -> None:
    with pytest.raises(CommandError, match="no COMMAND_ACK"):
        asyncio.run(_command_across_a_stall(None))


def test_a_wait_satisfied_after_a_noted_stall_longer_than_its_timeout_succeeds() -> None:
    async def main() -> tuple[bool, bool]:
        vehicle = Responder(free_port_block(1))
        stalls = StationStalls()
        try:
            async with LinkHub() as hub:
                link = await _linked(hub, vehicle)
                on_stalls = asyncio.create_task(
                    link.wait_for(lambda t: t.armed, TRY_S, clock=stalls.clock))
                on_wall = asyncio.create_task(link.wait_for(lambda t: t.armed, TRY_S))
                await asyncio.sleep(0)  # both are waiting
                _stall(stalls)
                await asyncio.sleep(0.1)  # the wall-time wait sees its timeout first
                vehicle.heartbeat(armed=True)
                return await on_stalls, await on_wall
        finally:
            vehicle.sock.close()

    on_stalls, on_wall = asyncio.run(main())
    assert on_stalls and not on_wall
