"""The links of a fleet (`LinkHub`): one endpoint per connection URL shared by the vehicles that
name it, one signing state per key, the GCS HEARTBEAT to every vehicle at 1 Hz with the signing
timestamps kept persisted, and everything closed on exit (``async with LinkHub() as hub``)."""

from __future__ import annotations

import asyncio
import contextlib

from gcs.errors import LinkError
from gcs.flight.link.endpoints import Endpoint, ThreadedEndpoint, UdpEndpoint
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.signing import LinkSigning
from gcs.wire import SigningKey, is_udp_url

__all__ = ["LinkHub"]


class LinkHub:
    """The endpoints of a fleet, their GCS heartbeats (1 Hz) and their vehicles.

    Use as ``async with LinkHub() as hub: link = await hub.add(vehicle_id, url, system_id)``;
    vehicles sharing a URL share one endpoint.
    """

    def __init__(self, heartbeat_period: float = 1.0,
                 decode_ids: frozenset[int] | None = None) -> None:
        self.decode_ids = decode_ids
        """Message ids UDP endpoints decode (None: all; `DECODED_IDS`: what the link reads)."""
        self.endpoints: dict[str, Endpoint] = {}
        self.links: dict[str, VehicleLink] = {}
        self.signers: dict[bytes, LinkSigning] = {}
        """One signing state per key (vehicles sharing a key share its timestamp)."""
        self.heartbeat_period = heartbeat_period
        self._heartbeat_task: asyncio.Task[None] | None = None

    async def __aenter__(self) -> LinkHub:
        self._heartbeat_task = asyncio.create_task(self._heartbeats(), name="gcs-heartbeat")
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def add(self, vehicle_id: str, url: str, system_id: int,
                  component_id: int = 1, *, signing_key: SigningKey | None = None,
                  peer: tuple[str, int] | None = None) -> VehicleLink:
        """A link to one vehicle; `signing_key` signs it, `peer` pins its address up front."""
        signing = None
        if signing_key is not None:
            signing = self.signers.get(signing_key.secret)
            if signing is None:
                try:
                    signing = LinkSigning(signing_key)
                except OSError as exc:
                    raise LinkError(f"{vehicle_id}: signing key {signing_key}: {exc}") from exc
                self.signers[signing_key.secret] = signing
        endpoint = self.endpoints.get(url)
        if endpoint is None:
            endpoint = (UdpEndpoint(url, self.decode_ids) if is_udp_url(url)
                        else ThreadedEndpoint(url))
            await endpoint.open()
            self.endpoints[url] = endpoint
        link = VehicleLink(vehicle_id, endpoint, system_id, component_id, signing=signing,
                           peer=peer)
        self.links[vehicle_id] = link
        return link

    async def _heartbeats(self) -> None:
        """The GCS HEARTBEAT and a TIMESYNC request (latency) to every vehicle each period;
        signing reservations kept ahead."""
        while True:
            for i, link in enumerate(list(self.links.values())):
                link.send_heartbeat()
                link.send_timesync()
                if i % 10 == 9:  # a 100-vehicle round is milliseconds: let a tick through
                    await asyncio.sleep(0)
            for signing in self.signers.values():
                signing.reserve()
            await asyncio.sleep(self.heartbeat_period)

    async def close(self) -> None:
        """Stop the heartbeats and close every endpoint."""
        if self._heartbeat_task is not None:
            self._heartbeat_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._heartbeat_task
            self._heartbeat_task = None
        for endpoint in self.endpoints.values():
            endpoint.close()
        await asyncio.sleep(0)  # transports release their sockets on the next loop turn
