"""A fleet of PX4-like mock vehicles on one asyncio loop (`MockFleet`), and their placement.

Each mock vehicle follows PX4 SITL's port convention (`px4`): instance i listens on UDP
``listen_base_port + i`` (`OFFBOARD_VEHICLE_BASE_PORT` + i) and sends to ``gcs_base_port + i``
(`OFFBOARD_GCS_BASE_PORT` + i) on 127.0.0.1 until it hears its first partner, then to that
partner (as PX4's UDP link latches it); system id i + 1, component 1. With `gcs_link_port`
each vehicle also has a GCS link, like PX4's: its own socket on a free port, sending everything
to ``host:gcs_link_port`` (PX4: 14550) until a ground station answers, so QGroundControl or
MAVProxy can watch (and command) the vehicles beside the GCS that flies them. So ``fleetplan
fly`` runs unchanged against the mock or PX4 SITL. The vehicles' protocol and rules are in
`gcs.sim.vehicle`; their motion is `gcs.sim.model.FleetModel`, integrated at `physics_rate`
(>= 100 Hz) for the whole fleet at once.

Python API::

    async with MockFleet(4, homes=[[0, 0, 0], [2, 0, 0], ...], gcs_base_port=24540,
                         listen_base_port=24580, settle_time=1.0) as mock:
        fleet_file = mock.fleet_dict()        # what `gcs.flight.run.executor` needs to fly them
        mock.vehicles[2].faults.heartbeats = False
        print(mock.vehicles[0].position_world)

or run it as a process: ``fleetplan mock --vehicles 4`` (see `gcs.cli.mock_cmd`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import functools
import logging
import socket
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gcs import frames
from gcs.autopilot import px4
from gcs.sim.config import AUTOPILOTS, MockConfig
from gcs.sim.core import VehicleContext
from gcs.sim.links import UdpLink
from gcs.sim.model import FleetModel
from gcs.sim.vehicle import MockVehicle
from gcs.wire import Datagrams

__all__ = ["DEFAULT_WORLD_ORIGIN", "MockFleet", "homes_under"]

_log = logging.getLogger(__name__)

#: PX4 SITL's default home (Zurich), used as the mock's geodetic world origin.
DEFAULT_WORLD_ORIGIN = frames.Geodetic(47.397742, 8.545594, 488.0)
#: A wake-up of the fleet's loop this much late is its own process stalling (in-process with
#: the GCS, the GCS stalled too): the vehicles do not count it as offboard silence.
OWN_STALL_S = 0.1


def homes_under(starts: ArrayLike) -> list[list[float]]:
    """Homes on the ground (z = 0) right under each start: the climb to the start is vertical
    (how `fleetplan fly --mock` and the service place mocks); where two columns are nearer
    than R, the higher start climbs first (`gcs.flight.run.climb_order`)."""
    return [[float(s[0]), float(s[1]), 0.0] for s in np.asarray(starts, dtype=float)]


class MockFleet:
    """N mock PX4 vehicles on one asyncio loop, integrated together.

    `homes` are the vehicles' homes (LOCAL_NED origins) in the world frame ENU; by default a
    row 2 m apart along x. Ports: vehicle i sends to ``host:gcs_base_port + min(i,
    max_port_offset)`` (`max_port_offset=9` reproduces PX4 SITL from instance 10 on, 0 puts the
    whole fleet behind one port) and listens on ``host:listen_base_port + i``.
    `gcs_link_port`: also give each vehicle a GCS link sending to ``host:gcs_link_port``
    (`gcs.autopilot.px4.GCS_LINK_PORT` for QGroundControl; None, the default: no GCS link).
    `signing_key` (32 bytes): every vehicle starts with it, as if provisioned earlier; without
    it they accept a key by SETUP_SIGNING (`gcs.sim.vehicle`).
    Behaviour: `config`, or the preset named by the keyword `realism` ("ideal", the default, or
    "px4": `MockConfig.px4_like`), then any other keyword overrides one `MockConfig` field;
    `autopilots` (one per vehicle, ``px4`` or ``ardupilot``) gives vehicles their own
    autopilot's rules (`MockConfig.autopilot`), for a mixed fleet.
    """

    def __init__(self, count: int | None = None, *, homes: Sequence[ArrayLike] | None = None,
                 world_origin: frames.Geodetic = DEFAULT_WORLD_ORIGIN, host: str = "127.0.0.1",
                 gcs_base_port: int = px4.OFFBOARD_GCS_BASE_PORT,
                 listen_base_port: int = px4.OFFBOARD_VEHICLE_BASE_PORT,
                 max_port_offset: int | None = None, config: MockConfig | None = None,
                 seed: int | None = None, signing_key: bytes | None = None,
                 gcs_link_port: int | None = None, autopilots: Sequence[str] | None = None,
                 **config_overrides: Any) -> None:
        if homes is None:
            if count is None:
                raise ValueError("give the vehicle count or their homes")
            homes = [[2.0 * i, 0.0, 0.0] for i in range(count)]
        elif count is not None and count != len(homes):
            raise ValueError(f"{count} vehicles but {len(homes)} homes")
        realism = config_overrides.pop("realism", None)
        if config is None:
            config = MockConfig.preset(realism or "ideal")
        elif realism is not None and realism != config.realism:
            raise ValueError(f"realism {realism!r} but the config given is {config.realism!r}")
        self.config = config
        for key, value in config_overrides.items():
            if not hasattr(self.config, key):
                raise TypeError(f"unknown mock setting {key!r}")
            setattr(self.config, key, value)
        if self.config.physics_rate < 100.0:
            raise ValueError("physics_rate must be at least 100 Hz")
        self.world_origin = world_origin
        self.host = host
        self.gcs_base_port = gcs_base_port
        self.listen_base_port = listen_base_port
        self.gcs_link_port = gcs_link_port
        self.seed = self.config.seed if seed is None else seed
        """Seed of the fleet's random processes (`MockConfig.seed` unless given)."""
        self.model = FleetModel(len(homes), self.config.limits, self.config.estimate_noise,
                                self.seed)
        context = VehicleContext(self.now, self.model, self.config, world_origin, self.seed)
        if autopilots is not None and len(autopilots) != len(homes):
            raise ValueError(f"{len(autopilots)} autopilots for {len(homes)} vehicles")
        for kind in [self.config.autopilot, *(autopilots or ())]:
            if kind not in AUTOPILOTS:
                raise ValueError(f"autopilot must be one of {', '.join(AUTOPILOTS)}, got "
                                 f"{kind!r}")
        self.vehicles: list[MockVehicle] = []
        for i, home in enumerate(homes):
            offset = i if max_port_offset is None else min(i, max_port_offset)
            own = context if autopilots is None else dataclasses.replace(
                context, config=dataclasses.replace(self.config, autopilot=autopilots[i]))
            self.vehicles.append(MockVehicle(
                own, i, home, (host, gcs_base_port + offset), (host, listen_base_port + i)))
            if signing_key is not None:  # the key already on the vehicles' SD cards
                self.vehicles[-1].set_signing_key(signing_key)
        self._start = time.monotonic()
        self._task: asyncio.Task[None] | None = None
        self.physics_steps = 0
        self.errors = 0
        """Physics steps that raised (each vehicle counts its own in `MockVehicle.errors`)."""

    @property
    def boot_monotonic(self) -> float:
        """The `time.monotonic()` instant of the vehicles' boot (their time_boot_ms 0): a
        process on the same machine turns their timestamps into its own clock with it."""
        return self._start

    def now(self) -> float:
        """Seconds since the mock started (its boot clock)."""
        return time.monotonic() - self._start

    def gcs_url(self, index: int) -> str:
        """The pymavlink URL the GCS opens for vehicle `index`."""
        return f"udpin:{self.host}:{self.vehicles[index].gcs_port}"

    def fleet_dict(self, ids: Sequence[str] | None = None) -> dict[str, Any]:
        """A fleet file (`gcs.fleet.fleetfile` format) for these vehicles: world-frame homes,
        and each vehicle's source address as its `peer`."""
        ids = list(ids) if ids is not None else [f"uav{i + 1}" for i in range(len(self.vehicles))]
        return {"vehicles": [
            {"id": vid, "connection": self.gcs_url(i), "system_id": v.system_id,
             "home": v.home_world.tolist(),
             # the mock's own address, known here: pinned up front, never at first contact
             "peer": f"{v.listen_address[0]}:{v.listen_address[1]}"}
            for i, (vid, v) in enumerate(zip(ids, self.vehicles, strict=True))]}

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        for vehicle in self.vehicles:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                sock.bind(vehicle.listen_address)
            except OSError as exc:
                sock.close()
                await self.stop()
                raise OSError(f"mock vehicle {vehicle.index}: cannot bind "
                              f"{vehicle.listen_address}: {exc}") from exc
            sock.setblocking(False)
            # No error callback: nobody listening yet on the GCS port is fine (PX4 keeps
            # sending too).
            transport, _ = await loop.create_datagram_endpoint(
                functools.partial(Datagrams, vehicle.received_datagram), sock=sock)
            vehicle.attach(transport)
            if self.gcs_link_port is not None:
                await self._open_gcs_link(vehicle)
        self._start = time.monotonic()
        self._task = asyncio.create_task(self._run(), name="mock-fleet")

    async def _open_gcs_link(self, vehicle: MockVehicle) -> None:
        """The vehicle's GCS link: a socket on a free port sending to `gcs_link_port`."""
        loop = asyncio.get_running_loop()
        links: list[UdpLink] = []

        def received(data: bytes, address: tuple[str, int]) -> None:
            vehicle.received_datagram(data, address, links[0])

        transport, _ = await loop.create_datagram_endpoint(
            functools.partial(Datagrams, received), local_addr=(self.host, 0))
        assert self.gcs_link_port is not None
        links.append(vehicle.attach_link(UdpLink("gcs", transport,
                                                 (self.host, self.gcs_link_port))))

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        for vehicle in self.vehicles:
            vehicle.detach()

    async def __aenter__(self) -> MockFleet:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    async def run_forever(self) -> None:
        """Start (if needed) and run until cancelled."""
        if self._task is None:
            await self.start()
        assert self._task is not None
        await self._task

    async def _run(self) -> None:
        step = 1.0 / self.config.physics_rate
        simulated = self.now()
        while True:
            now = self.now()
            # integrate in steps no longer than 1/physics_rate, however late we woke up
            while simulated + step <= now:
                try:
                    self.model.step(step)
                except Exception:  # never stop the fleet; the model undoes bad rows itself
                    self.errors += 1
                    if self.errors <= 3:
                        _log.exception("mock fleet: physics step failed")
                simulated += step
                self.physics_steps += 1
            for vehicle in self.vehicles:  # one vehicle's failure must not silence the others
                try:
                    vehicle.tick(now)
                except Exception:
                    vehicle.record_error("in its flight rules")
                try:
                    vehicle.send_telemetry(now)
                except Exception:
                    vehicle.record_error("sending telemetry")
            wake = simulated + step
            await asyncio.sleep(max(0.0, wake - self.now()))
            late = self.now() - wake
            if late > OWN_STALL_S:  # this process stalled: not the GCS's silence
                for vehicle in self.vehicles:
                    vehicle.forgive_stall(late)
