"""A loopback UDP proxy between a ground station and mock vehicles that drops, delays,
reorders and blackholes datagrams per vehicle: the radio links of the field, for the chaos
benchmark (`bench/chaos.py`) and the tests.

Vehicle i sends to ``host:vehicle_base_port + i`` (give the mocks that as their
`gcs_base_port`); the proxy forwards each datagram from a socket of its own to the station's
port for that vehicle (``gcs_ports[i]``), and the station's answers back to the vehicle's
address. So the station sees every vehicle at the proxy's address (`peer`), which a fleet file
pins (`fleet_dict`).

Each direction of each vehicle's link is judged per datagram by its `LinkFaults`, which may be
changed at any time (or on a schedule, `run_schedule`): `blackhole` drops everything, `loss`
each datagram at random, and every datagram that passes waits `delay` plus a uniform random
share of `jitter` (so datagrams closer together than the jitter arrive reordered). Drops are
independent draws from one seeded generator: a run is reproducible for the same traffic.
"""

from __future__ import annotations

import asyncio
import functools
import random
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from gcs.sim.ports import free_mock_fleet_ports, free_udp_base

__all__ = ["ChaosProxy", "LinkCounts", "LinkFaults"]


@dataclass(frozen=True)
class LinkFaults:
    """What one vehicle's link does to its datagrams, both directions."""

    loss: float = 0.0
    """Fraction of the datagrams dropped, each direction independently (0..1)."""
    delay: float = 0.0
    """Seconds every datagram waits."""
    jitter: float = 0.0
    """Up to this many seconds more, uniformly at random per datagram (reorders them)."""
    blackhole: bool = False
    """Drop everything (a radio out of range)."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.loss <= 1.0:
            raise ValueError(f"loss must be within [0, 1], got {self.loss}")
        if self.delay < 0.0 or self.jitter < 0.0:
            raise ValueError("delay and jitter must be >= 0")


@dataclass
class LinkCounts:
    """Datagrams of one vehicle's link, per direction (up: vehicle to station)."""

    up: int = 0
    up_dropped: int = 0
    down: int = 0
    down_dropped: int = 0


@dataclass
class _Link:
    index: int
    faults: LinkFaults
    counts: LinkCounts = field(default_factory=LinkCounts)
    vehicle: Any = None
    """The vehicle's address (learned from its first datagram)."""
    to_vehicle: asyncio.DatagramTransport | None = None
    to_station: asyncio.DatagramTransport | None = None


class _Side(asyncio.DatagramProtocol):
    """One socket of a link: datagrams in are handed to the proxy with their direction."""

    def __init__(self, proxy: ChaosProxy, link: _Link, up: bool) -> None:
        self.proxy, self.link, self.up = proxy, link, up

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.proxy._forward(self.link, self.up, data, addr)

    def error_received(self, exc: Exception) -> None:
        """Nobody listening on the other side yet: as a radio, keep going."""


class ChaosProxy:
    """Per-vehicle faulty links between a station and its vehicles (see the module)."""

    def __init__(self, gcs_ports: Sequence[int], vehicle_base_port: int, *,
                 host: str = "127.0.0.1", seed: int = 0,
                 faults: LinkFaults | None = None) -> None:
        self.host = host
        self.gcs_ports = list(gcs_ports)
        self.vehicle_base_port = vehicle_base_port
        self._rng = random.Random(seed)
        self._links = [_Link(i, faults or LinkFaults()) for i in range(len(self.gcs_ports))]
        self._loop: asyncio.AbstractEventLoop | None = None

    async def __aenter__(self) -> ChaosProxy:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.stop()

    async def start(self) -> None:
        """Open both sockets of every link; when one cannot be opened (its port taken), close
        those already open and raise."""
        loop = asyncio.get_running_loop()
        self._loop = loop
        try:
            for link in self._links:
                link.to_vehicle, _ = await loop.create_datagram_endpoint(
                    functools.partial(_Side, self, link, True),
                    local_addr=(self.host, self.vehicle_base_port + link.index))
                link.to_station, _ = await loop.create_datagram_endpoint(
                    functools.partial(_Side, self, link, False), local_addr=(self.host, 0))
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        """Close every socket (datagrams still waiting are dropped)."""
        for link in self._links:
            for transport in (link.to_vehicle, link.to_station):
                if transport is not None:
                    transport.close()
            link.to_vehicle = link.to_station = None

    # ------------------------------------------------------------------ configuration

    def set(self, index: int | None = None, **changes: Any) -> None:
        """Change the faults of vehicle `index` (None: every vehicle), e.g. ``loss=0.2``."""
        for link in self._links if index is None else [self._links[index]]:
            link.faults = replace(link.faults, **changes)

    def faults(self, index: int) -> LinkFaults:
        return self._links[index].faults

    def counts(self, index: int) -> LinkCounts:
        return self._links[index].counts

    def peer(self, index: int) -> str:
        """``host:port`` the station hears vehicle `index` from (its fleet file's `peer`)."""
        transport = self._links[index].to_station
        assert transport is not None, "start the proxy first"
        host, port = transport.get_extra_info("sockname")[:2]
        return f"{host}:{port}"

    def fleet_dict(self, fleet: dict[str, Any]) -> dict[str, Any]:
        """`fleet` (a mock fleet's `fleet_dict`) through the proxy: each vehicle's station
        port, pinned to its link here."""
        vehicles = [{**v, "connection": f"udpin:{self.host}:{self.gcs_ports[i]}",
                     "peer": self.peer(i)} for i, v in enumerate(fleet["vehicles"])]
        return {**fleet, "vehicles": vehicles}

    @classmethod
    def on_free_ports(cls, count: int, **kwargs: Any) -> tuple[ChaosProxy, dict[str, int]]:
        """A proxy for `count` vehicles on ports free now, and the `MockFleet` port keywords
        that send the mocks' datagrams through it."""
        mock = free_mock_fleet_ports(count)
        station = free_udp_base(range(count))
        proxy = cls([station + i for i in range(count)], mock["gcs_base_port"], **kwargs)
        return proxy, mock

    async def run_schedule(self, steps: Sequence[tuple[float, int | None, dict[str, Any]]],
                           ) -> None:
        """Apply each (seconds from now, vehicle index or None, changes) in time order."""
        loop = asyncio.get_running_loop()
        start = loop.time()
        for at, index, changes in sorted(steps, key=lambda step: step[0]):
            await asyncio.sleep(max(0.0, start + at - loop.time()))
            self.set(index, **changes)

    # ------------------------------------------------------------------ forwarding

    def _forward(self, link: _Link, up: bool, data: bytes, addr: Any) -> None:
        counts = link.counts
        if up:
            link.vehicle = addr
            counts.up += 1
        else:
            counts.down += 1
        faults = link.faults
        if faults.blackhole or (faults.loss > 0.0 and self._rng.random() < faults.loss):
            if up:
                counts.up_dropped += 1
            else:
                counts.down_dropped += 1
            return
        transport = link.to_station if up else link.to_vehicle
        target = (self.host, self.gcs_ports[link.index]) if up else link.vehicle
        if transport is None or target is None:
            return
        wait = faults.delay + (self._rng.uniform(0.0, faults.jitter) if faults.jitter else 0.0)
        if wait <= 0.0:
            transport.sendto(data, target)
        else:
            assert self._loop is not None
            self._loop.call_later(wait, _send, transport, data, target)


def _send(transport: asyncio.DatagramTransport, data: bytes, target: Any) -> None:
    if not transport.is_closing():
        transport.sendto(data, target)
