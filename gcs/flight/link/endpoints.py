"""MAVLink connections: the sockets (and reader threads) that vehicles share, routing by system id.

- `Endpoint`: one connection, shared by every vehicle whose fleet entry names the same URL.
  PX4 SITL from instance 10 on, and telemetry radio networks, put several system ids behind one
  port, so an endpoint hands each packet to the `Receiver` registered for its system id.
  Traffic from system id 0 (PX4's undecodable development messages) and from ids no vehicle is
  registered for is dropped and counted.
- `UdpEndpoint`: ``udpin:HOST:PORT`` (also ``udp:``; bind, and send each vehicle's traffic only
  to its pinned peer: what PX4's offboard link needs) or ``udpout:HOST:PORT`` (send to a fixed
  address), on the running asyncio loop. Each datagram is decoded on its own by a fresh parser
  (`gcs.wire.parse_datagram`): garbage is counted and cannot swallow the next real packet. A
  datagram holding one whole packet (header and CRC checked, `gcs.wire.peek_packet`) that its
  receiver refuses on the header (another address, another component, unsigned while a key
  is set) is handed on undecoded, and so is, with `decode_ids`, one of another message id.
- `ThreadedEndpoint`: any other pymavlink URL (serial ports, ``tcp:``), opened with pymavlink's
  `mavutil` on a reader thread (its vehicles are pinned by component only: there is no address).

Whether a packet is admitted (pinned peer, component, signature) is the receiver's decision
(`gcs.flight.link.link.VehicleLink`).
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time
from typing import Any, Protocol

from gcs import wire
from gcs.errors import LinkError
from gcs.wire import (
    GCS_COMPONENT_ID,
    GCS_SYSTEM_ID,
    Datagrams,
    PacketHeader,
    mavlink,
    parse_datagram,
    parse_udp_url,
    peek_packet,
)

__all__ = ["Endpoint", "Receiver", "ThreadedEndpoint", "UdpEndpoint"]


class Receiver(Protocol):
    """What an endpoint delivers one system id's packets to (a `VehicleLink`)."""

    system_id: int
    pinned: bool
    """Whether its peer is known: before that every packet is decoded (it pins the peer)."""
    peer_address: Any
    """Where its traffic goes (None: nowhere yet)."""

    def receive(self, msg: Any, address: Any, now: float) -> None:
        """A decoded message from `address`, received at `now`."""

    def receive_skipped(self, header: PacketHeader, packet: bytes, address: Any) -> None:
        """One whole valid packet from `address` that the endpoint did not decode (an id it
        does not read, or one `refuses` drops)."""

    def refuses(self, header: PacketHeader, address: Any) -> bool:
        """Whether a packet with `header` from `address` is dropped whatever its payload
        (judged on the header alone, so that it is never decoded)."""


class Endpoint:
    """One MAVLink connection shared by the receivers registered on it (base class)."""

    def __init__(self, url: str, decode_ids: frozenset[int] | None = None) -> None:
        self.url = url
        self.decode_ids = decode_ids
        """Message ids decoded in full (None: all). Others are dropped after a header check
        (`UdpEndpoint`), counted in `skipped` and in their vehicle's `Telemetry.skipped`."""
        self.mav = mavlink.MAVLink(None, srcSystem=GCS_SYSTEM_ID, srcComponent=GCS_COMPONENT_ID)
        self.mav.robust_parsing = True
        self.vehicles: dict[int, Receiver] = {}
        self.dropped_unknown = 0
        """Messages dropped because their system id is 0 or not registered."""
        self.garbage_datagrams = 0
        """Datagrams holding bytes that were not a valid packet (junk, truncated, bad CRC)."""
        self.garbage_bytes = 0
        self.bytes_sent = 0
        self.messages_received = 0
        """Valid messages received (decoded or skipped), whoever sent them."""
        self.skipped = 0
        """Messages of an id outside `decode_ids`, dropped before decoding."""
        self.refused = 0
        """Messages their receiver refused on the header alone (`Receiver.refuses`), never
        decoded; each is also counted by the receiver's security counters."""

    def register(self, receiver: Receiver) -> None:
        """Route `receiver.system_id`'s packets to `receiver` (one receiver per system id)."""
        if receiver.system_id in self.vehicles:
            raise LinkError(f"system id {receiver.system_id} registered twice on {self.url}")
        self.vehicles[receiver.system_id] = receiver

    def _dispatch(self, msg: Any, address: Any, now: float) -> None:
        """Count a decoded message and hand it to its system id's receiver."""
        if msg.get_type() == "BAD_DATA":
            self.garbage_datagrams += 1
            self.garbage_bytes += len(msg.data)
            return
        self.messages_received += 1
        receiver = self.vehicles.get(msg.get_srcSystem())
        if receiver is None:
            self.dropped_unknown += 1
            return
        receiver.receive(msg, address, now)

    def pack(self, msg: Any) -> bytes:
        """`msg` as bytes on this connection's unsigned packer (assigns its sequence number)."""
        return wire.pack(msg, self.mav)

    def send_bytes(self, system_id: int, buf: bytes) -> None:
        """Send an already packed message to `system_id`'s pinned peer."""
        raise NotImplementedError

    async def open(self) -> None:
        """Open the connection (raises `LinkError` when it cannot)."""
        raise NotImplementedError

    def close(self) -> None:
        """Close the connection; nothing is received or sent afterwards."""
        raise NotImplementedError


class UdpEndpoint(Endpoint):
    """A UDP endpoint on the running asyncio loop (``udpin``/``udp`` or ``udpout``)."""

    def __init__(self, url: str, decode_ids: frozenset[int] | None = None) -> None:
        super().__init__(url, decode_ids)
        self.kind, self.host, self.port = parse_udp_url(url)
        self.send_errors = 0
        self._transport: asyncio.DatagramTransport | None = None
        self._sock: socket.socket | None = None

    async def open(self) -> None:
        loop = asyncio.get_running_loop()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            if self.kind == "in":
                sock.bind((self.host, self.port))
            else:
                sock.bind(("0.0.0.0", 0))
        except OSError as exc:
            sock.close()
            raise LinkError(f"cannot open {self.url}: {exc}") from exc
        sock.setblocking(False)
        self._sock = sock
        self._transport, _ = await loop.create_datagram_endpoint(
            lambda: Datagrams(self.received, self._send_error), sock=sock)

    def close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    def _send_error(self, exc: Exception) -> None:
        self.send_errors += 1

    def received(self, data: bytes, addr: Any) -> None:
        """One datagram from `addr`: refused or skipped on its header, or decoded on its own
        and dispatched."""
        now = time.monotonic()
        header = peek_packet(data)
        if header is not None and self._skip(header, data, addr):
            return
        parsed = parse_datagram(data)  # a fresh parser for every datagram
        if parsed.garbage_bytes:
            self.garbage_datagrams += 1
            self.garbage_bytes += parsed.garbage_bytes
        for msg in parsed.messages:
            self._dispatch(msg, addr, now)

    def _skip(self, header: PacketHeader, data: bytes, addr: Any) -> bool:
        """Hand on undecoded a datagram that is one whole packet (CRC checked, `header`) and
        that its receiver refuses on the header (another address than its pinned peer,
        another component, unsigned while it has a key: a flood of them costs a header check
        each, never a decode), or whose id is outside `decode_ids` for a pinned receiver.
        False: decode it in full (before its receiver is pinned, everything it admits is)."""
        receiver = self.vehicles.get(header.system)
        if receiver is not None and receiver.refuses(header, addr):
            self.messages_received += 1
            self.refused += 1
            receiver.receive_skipped(header, data, addr)  # counted, and dropped, there
            return True
        if self.decode_ids is None or header.msg_id in self.decode_ids:
            return False
        if receiver is not None and not receiver.pinned:
            return False
        self.messages_received += 1
        self.skipped += 1
        if receiver is None:
            self.dropped_unknown += 1
        else:
            receiver.receive_skipped(header, data, addr)
        return True

    def _address(self, system_id: int) -> Any:
        """Where `system_id`'s traffic goes: udpout's fixed address, else its pinned peer
        (None before it is pinned: nothing is sent to an address it did not speak from)."""
        if self.kind == "out":
            return (self.host, self.port)
        receiver = self.vehicles.get(system_id)
        return None if receiver is None else receiver.peer_address

    def send_bytes(self, system_id: int, buf: bytes) -> None:
        address = self._address(system_id)
        if self._sock is None or address is None:
            return
        try:
            self._sock.sendto(buf, address)
            self.bytes_sent += len(buf)
        except (BlockingIOError, OSError):
            self.send_errors += 1


class ThreadedEndpoint(Endpoint):
    """Any other pymavlink URL (serial port, tcp): `mavutil` on a reader thread.

    Writes go to the one underlying port (a radio network broadcasts), so routing by system id
    only happens on receive.
    """

    def __init__(self, url: str) -> None:
        super().__init__(url)
        self._conn: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()

    async def open(self) -> None:
        from pymavlink import mavutil

        loop = asyncio.get_running_loop()
        try:
            self._conn = await loop.run_in_executor(None, lambda: mavutil.mavlink_connection(
                self.url, source_system=GCS_SYSTEM_ID, source_component=GCS_COMPONENT_ID,
                dialect="common", autoreconnect=True))
        except Exception as exc:  # pymavlink raises many kinds
            raise LinkError(f"cannot open {self.url}: {exc}") from exc
        self.mav = self._conn.mav

        def reader() -> None:
            while not self._stop.is_set():
                try:
                    msg = self._conn.recv_match(blocking=True, timeout=0.2)
                except Exception:
                    continue
                if msg is not None:
                    now = time.monotonic()
                    loop.call_soon_threadsafe(self._dispatch, msg, None, now)

        self._thread = threading.Thread(target=reader, name=f"mavlink {self.url}", daemon=True)
        self._thread.start()

    def pack(self, msg: Any) -> bytes:
        with self._lock:  # the reader thread's connection shares this encoder
            return wire.pack(msg, self.mav)

    def send_bytes(self, system_id: int, buf: bytes) -> None:
        if self._conn is None:
            return
        with self._lock:
            self._conn.write(buf)
            self.bytes_sent += len(buf)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._conn is not None:
            with contextlib.suppress(Exception):
                self._conn.close()
            self._conn = None
