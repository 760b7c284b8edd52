"""A mock vehicle's UDP MAVLink links, addressed as PX4's UDP links address their partner.

PX4's UDP link sends to its configured remote (the offboard link: 127.0.0.1:14540 + i; the GCS
link: 14550) until it has a partner, then latches the first one it hears (a localhost remote
latches at once; `MavlinkReceiver`: "partner IP") and keeps it: a later packet from another
address is still handled but never pulls the link's traffic away. The mock latches at the
first valid MAVLink message (PX4: the first datagram, even an undecodable one).
"""

from __future__ import annotations

import asyncio

__all__ = ["UdpLink"]


class UdpLink:
    """One UDP link of a vehicle: its socket's transport and where it sends."""

    def __init__(self, name: str, transport: asyncio.DatagramTransport,
                 remote: tuple[str, int]) -> None:
        self.name = name
        """"offboard" (the API link fleetplan flies through) or "gcs" (a ground station's)."""
        self.transport = transport
        self.remote = remote
        """The configured remote, used until a partner is latched."""
        self.partner: tuple[str, int] | None = None
        """The latched partner (None: nobody has spoken on this link yet)."""

    @property
    def address(self) -> tuple[str, int]:
        """Where this link sends: its partner once latched, else the configured remote."""
        return self.partner if self.partner is not None else self.remote

    @property
    def local_address(self) -> tuple[str, int]:
        """The (host, port) this link's socket is bound to."""
        host, port = self.transport.get_extra_info("sockname")[:2]
        return (str(host), int(port))

    def heard(self, address: tuple[str, int]) -> None:
        """A valid message came from `address`: latch it if this is the first."""
        if self.partner is None:
            self.partner = address

    def sendto(self, data: bytes) -> None:
        """Send one datagram to `address` (nothing once closed)."""
        if not self.transport.is_closing():
            self.transport.sendto(data, self.address)

    def close(self) -> None:
        self.transport.close()
