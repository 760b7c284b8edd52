"""MAVLink links to vehicles: sockets, routing by system id, heartbeats, commands, telemetry.

pymavlink is the wire format (its MAVLink 2 `common` dialect encodes and decodes); the sockets
are asyncio's, so every link runs on the caller's event loop.

- `Endpoint`: one connection (one UDP socket), shared by every vehicle whose fleet entry names
  the same URL. PX4 SITL from instance 10 on, and telemetry radio networks, put several system
  ids behind one port, so an endpoint routes by system id. Each UDP datagram is decoded on its
  own by a fresh parser (`gcs.wire.parse_datagram`): garbage is counted and cannot swallow the
  next real packet. Traffic from system id 0 (PX4's undecodable development messages) and from
  ids no vehicle is registered for is dropped and counted. With `decode_ids` (e.g.
  `DECODED_IDS`, what this module reads), a datagram holding one packet of another message id
  is dropped after a header and CRC check (`gcs.wire.peek_packet`), before any decoding, yet
  still counted for link quality once it passed the vehicle's pinning and signing checks.
- `VehicleLink`: one vehicle on an endpoint. Its *pinned peer* (source address + autopilot
  component) is fixed by its first accepted packet, or up front by the fleet file's ``peer``;
  packets with its system id from any other address are dropped and counted as security
  events, and nothing is ever sent anywhere but the pinned address. With a signing key
  (`gcs.flight.signing`), everything it sends is signed and every unsigned, wrongly signed or
  replayed packet is dropped and counted. Its telemetry (HEARTBEAT mode/armed/age,
  LOCAL_POSITION_NED, EXTENDED_SYS_STATE, GPS_GLOBAL_ORIGIN, HOME_POSITION, STATUSTEXT, the
  security counters; for `gcs.flight.health`: SYS_STATUS, BATTERY_STATUS, GPS_RAW_INT and
  sequence-number gaps); a non-finite position or velocity is never stored: it is counted and
  timestamped (`Telemetry.invalid_estimate_time`) for the monitor to flag. `command()` with
  COMMAND_ACK (from the pinned peer, for a pending command only), retries and duplicate-ACK
  tolerance, and `send_setpoint()`.
- `LinkHub`: opens the endpoints for a fleet, sends every vehicle the GCS HEARTBEAT at 1 Hz,
  keeps the signing timestamps persisted, closes everything on exit
  (``async with LinkHub() as hub``).

URLs: ``udpin:HOST:PORT`` (also ``udp:``; bind, and pin each vehicle at first contact: what
PX4's offboard link needs), ``udpout:HOST:PORT`` (send to a fixed address). Other pymavlink
URLs (serial ports, ``tcp:``) are opened with pymavlink's `mavutil` on a reader thread
(`ThreadedEndpoint`; pinned by component only, there being no address).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gcs import px4, wire
from gcs.errors import CommandError, LinkError
from gcs.flight.setpoints import Setpoint
from gcs.flight.signing import LinkSigning
from gcs.wire import (
    GCS_COMPONENT_ID,
    GCS_SYSTEM_ID,
    Datagrams,
    SigningKey,
    is_udp_url,
    mavlink,
    parse_datagram,
    parse_udp_url,
    peek_packet,
    result_name,
)

__all__ = [
    "DECODED_IDS",
    "GCS_COMPONENT_ID",
    "GCS_SYSTEM_ID",
    "Endpoint",
    "LinkHub",
    "SecurityCounters",
    "Telemetry",
    "ThreadedEndpoint",
    "UdpEndpoint",
    "VehicleLink",
    "mavlink",
    "result_name",
]

MessageCallback = Callable[["VehicleLink", Any, float], None]

_m = mavlink
#: The message ids `VehicleLink` reads (its telemetry, COMMAND_ACK) and the flight executor's
#: listener uses: with ``LinkHub(decode_ids=DECODED_IDS)`` every other id is dropped before
#: decoding (PX4's offboard link sends ~410 messages/s per vehicle, ~20 kinds, most unread).
DECODED_IDS = frozenset({
    _m.MAVLINK_MSG_ID_HEARTBEAT, _m.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    _m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, _m.MAVLINK_MSG_ID_COMMAND_ACK,
    _m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, _m.MAVLINK_MSG_ID_HOME_POSITION,
    _m.MAVLINK_MSG_ID_STATUSTEXT, _m.MAVLINK_MSG_ID_SYS_STATUS,
    _m.MAVLINK_MSG_ID_BATTERY_STATUS, _m.MAVLINK_MSG_ID_GPS_RAW_INT,
})


class Endpoint:
    """One MAVLink connection shared by the vehicles registered on it (base class)."""

    def __init__(self, url: str, decode_ids: frozenset[int] | None = None) -> None:
        self.url = url
        self.decode_ids = decode_ids
        """Message ids decoded in full (None: all). Others are dropped after a header check
        (`UdpEndpoint`), counted in `skipped` and in their vehicle's `Telemetry.skipped`."""
        self.mav = mavlink.MAVLink(None, srcSystem=GCS_SYSTEM_ID, srcComponent=GCS_COMPONENT_ID)
        self.mav.robust_parsing = True
        self.vehicles: dict[int, VehicleLink] = {}
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

    def register(self, link: VehicleLink) -> None:
        if link.system_id in self.vehicles:
            raise LinkError(f"system id {link.system_id} registered twice on {self.url}")
        self.vehicles[link.system_id] = link

    def _dispatch(self, msg: Any, address: Any, now: float) -> None:
        if msg.get_type() == "BAD_DATA":
            self.garbage_datagrams += 1
            self.garbage_bytes += len(msg.data)
            return
        self.messages_received += 1
        link = self.vehicles.get(msg.get_srcSystem())
        if link is None:
            self.dropped_unknown += 1
            return
        if link._accept(msg, address):
            link._handle(msg, now)

    def pack(self, msg: Any) -> bytes:
        """`msg` as bytes on this connection's unsigned packer (assigns its sequence number)."""
        return wire.pack(msg, self.mav)

    def send_bytes(self, system_id: int, buf: bytes) -> None:
        """Send an already packed message to `system_id`'s pinned peer."""
        raise NotImplementedError

    async def open(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
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
            lambda: Datagrams(self._received, self._send_error), sock=sock)

    def close(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    def _send_error(self, exc: Exception) -> None:
        self.send_errors += 1

    def _received(self, data: bytes, addr: Any) -> None:
        now = time.monotonic()
        if self.decode_ids is not None and self._skip(data, addr):
            return
        parsed = parse_datagram(data)  # a fresh parser for every datagram
        if parsed.garbage_bytes:
            self.garbage_datagrams += 1
            self.garbage_bytes += parsed.garbage_bytes
        for msg in parsed.messages:
            self._dispatch(msg, addr, now)

    def _skip(self, data: bytes, addr: Any) -> bool:
        """Drop `data` without decoding it if it is one whole packet (CRC checked) of an id
        outside `decode_ids`; False: decode it in full. A skipped packet passes the checks a
        decoded one does (pinned peer, autopilot component, signature and replay with a key)
        before its sequence number counts for link quality, so skipping never reads as loss
        and a spoofed one changes nothing but a security counter. It is no proof of life:
        that takes a decoded message. Before its vehicle is pinned, everything is decoded."""
        header = peek_packet(data)
        if header is None or header.msg_id in self.decode_ids:  # type: ignore[operator]
            return False
        link = self.vehicles.get(header.system)
        if link is not None and not link.pinned:
            return False
        self.messages_received += 1
        self.skipped += 1
        if link is None:
            self.dropped_unknown += 1
            return True
        if link._admit(header.component, addr,
                       lambda signing: signing.verify_packet(data, header.system,
                                                             header.component)):
            link.telemetry.skipped += 1
            _count_sequence(link.telemetry, header.seq)
        return True

    def _address(self, system_id: int) -> Any:
        """Where `system_id`'s traffic goes: udpout's fixed address, else its pinned peer
        (None before it is pinned: nothing is sent to an address it did not speak from)."""
        if self.kind == "out":
            return (self.host, self.port)
        link = self.vehicles.get(system_id)
        return None if link is None else link.peer_address

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


@dataclass
class _PendingCommand:
    command: int
    future: asyncio.Future[int]
    sent_at: float


@dataclass
class Telemetry:
    """The latest state one vehicle reported (times are `time.monotonic()` at reception)."""

    heartbeat_time: float | None = None
    message_time: float | None = None
    """Reception of the vehicle's latest message of any kind: the link's proof of life."""
    autopilot: int | None = None
    vehicle_type: int | None = None
    mode: px4.Px4Mode | None = None
    armed: bool = False
    system_status: int | None = None
    landed_state: int | None = None
    """MAV_LANDED_STATE from EXTENDED_SYS_STATE (1 on ground, 2 in air, 4 landing)."""
    position_ned: tuple[float, float, float] | None = None
    velocity_ned: tuple[float, float, float] | None = None
    position_time: float | None = None
    gps_origin: tuple[float, float, float] | None = None
    """GPS_GLOBAL_ORIGIN (lat deg, lon deg, alt m)."""
    home: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    """HOME_POSITION ((lat, lon, alt), (x, y, z) local NED)."""
    statustexts: deque[str] = field(default_factory=lambda: deque(maxlen=20))
    invalid_estimate_time: float | None = None
    """Reception of the latest LOCAL_POSITION_NED with a NaN or infinite position or velocity
    (never stored as the position): a fault for the monitor."""
    invalid_estimates: int = 0
    security: SecurityCounters = field(default_factory=lambda: SecurityCounters())

    # --- health (issue 12; read by gcs.flight.health) ---
    sensors_present: int | None = None
    """SYS_STATUS onboard_control_sensors_present (MAV_SYS_STATUS_SENSOR bits)."""
    sensors_enabled: int | None = None
    sensors_health: int | None = None
    battery_remaining: int | None = None
    """Battery remaining (%) from SYS_STATUS / BATTERY_STATUS; None when not reported."""
    battery_voltage: float = math.nan
    """Battery voltage (V) from SYS_STATUS."""
    gps_fix_type: int | None = None
    """GPS_RAW_INT fix_type (GPS_FIX_TYPE: 3 = 3D fix)."""
    gps_satellites: int | None = None
    gps_h_acc: float = math.nan
    """GPS_RAW_INT h_acc (m): horizontal position uncertainty."""
    gps_v_acc: float = math.nan
    warnings: deque[str] = field(default_factory=lambda: deque(maxlen=5))
    """STATUSTEXT of severity WARNING or worse."""
    seq_received: int = 0
    """Messages from the autopilot component counted for link quality (decoded or skipped)."""
    skipped: int = 0
    """Messages from the pinned autopilot dropped before decoding (an id the endpoint does not
    decode, `Endpoint.decode_ids`); they count for link quality, not as proof of life."""
    seq_lost: int = 0
    """Messages missing from the autopilot component's sequence numbers."""
    last_seq: int | None = None


@dataclass
class SecurityCounters:
    """Packets with this vehicle's system id that were dropped, by reason."""

    foreign_source: int = 0
    """From an address other than the pinned peer's (spoofing, hijacking)."""
    other_component: int = 0
    """From a component other than the autopilot's."""
    unsigned: int = 0
    """Unsigned although the vehicle has a key."""
    bad_signature: int = 0
    """Signed with another key, or altered."""
    replayed: int = 0
    """A correctly signed packet whose timestamp is not newer than its stream's last one."""

    def to_dict(self) -> dict[str, int]:
        return dict(vars(self))

    @property
    def total(self) -> int:
        return sum(vars(self).values())


def _count_sequence(tel: Telemetry, seq: int) -> None:
    """Link quality: a gap in the sender's sequence numbers (mod 256) counts as lost
    messages; a jump of 128 or more is taken as a restart or reordering, not a loss."""
    if tel.last_seq is not None:
        gap = (seq - tel.last_seq - 1) & 0xFF
        if gap < 128:
            tel.seq_lost += gap
    tel.last_seq = seq
    tel.seq_received += 1


def _health_message(tel: Telemetry, kind: str, msg: Any) -> None:
    """SYS_STATUS, BATTERY_STATUS and GPS_RAW_INT into `tel` (UINT16_MAX / -1 = unknown)."""
    if kind == "SYS_STATUS":
        tel.sensors_present = msg.onboard_control_sensors_present
        tel.sensors_enabled = msg.onboard_control_sensors_enabled
        tel.sensors_health = msg.onboard_control_sensors_health
        if msg.battery_remaining >= 0:
            tel.battery_remaining = int(msg.battery_remaining)
        if msg.voltage_battery not in (0, 0xFFFF):
            tel.battery_voltage = msg.voltage_battery / 1000.0
    elif kind == "BATTERY_STATUS":
        if msg.battery_remaining >= 0:
            tel.battery_remaining = int(msg.battery_remaining)
    else:  # GPS_RAW_INT
        tel.gps_fix_type = int(msg.fix_type)
        tel.gps_satellites = None if msg.satellites_visible == 255 else msg.satellites_visible
        tel.gps_h_acc = msg.h_acc / 1000.0 if msg.h_acc else math.nan
        tel.gps_v_acc = msg.v_acc / 1000.0 if msg.v_acc else math.nan


class VehicleLink:
    """One vehicle (system id, autopilot component) on an `Endpoint`."""

    def __init__(self, vehicle_id: str, endpoint: Endpoint, system_id: int,
                 component_id: int = 1, *, signing: LinkSigning | None = None,
                 peer: tuple[str, int] | None = None) -> None:
        self.vehicle_id = vehicle_id
        self.endpoint = endpoint
        self.system_id = system_id
        self.component_id = component_id
        self.signing = signing
        self.peer_address: Any = peer
        """The pinned peer's address (None until pinned; None for serial links)."""
        self.pinned = peer is not None
        self.mav = endpoint.mav
        """This vehicle's packer: the endpoint's, or its own sharing the key's signing state."""
        if signing is not None:
            self.mav = mavlink.MAVLink(None, srcSystem=GCS_SYSTEM_ID,
                                       srcComponent=GCS_COMPONENT_ID)
            self.mav.signing = signing.state
        self.telemetry = Telemetry()
        self.listeners: list[MessageCallback] = []
        """Called with (link, message, receive time) for every message of this vehicle."""
        self._texts = wire.StatusTexts()
        self._pending: dict[int, _PendingCommand] = {}
        self._echoes: dict[int, tuple[int, float]] = {}
        """command -> (result, until): the second ACK still due for a command PX4 ACKs twice."""
        self._waiters: list[tuple[Callable[[Telemetry], bool], asyncio.Future[None]]] = []
        self.duplicate_acks = 0
        self.setpoints_sent = 0
        endpoint.register(self)

    # ---------------------------------------------------------------- receiving

    def _accept(self, msg: Any, address: Any) -> bool:
        """Whether a decoded packet with this vehicle's system id is from its pinned peer
        (pinning it on the first acceptable packet) and, with a key, correctly signed and new."""
        return self._admit(msg.get_srcComponent(), address,
                           lambda signing: signing.verify(msg))

    def _admit(self, component: int, address: Any,
               verify: Callable[[LinkSigning], str | None]) -> bool:
        """`_accept` for a packet from `component` at `address` whose signature `verify`
        checks (None: good; else the security counter to raise); decoded or not."""
        counters = self.telemetry.security
        if self.pinned and address != self.peer_address:
            counters.foreign_source += 1
            return False
        if component != self.component_id:
            counters.other_component += 1
            return False
        if self.signing is not None:
            reason = verify(self.signing)
            if reason is not None:
                setattr(counters, reason, getattr(counters, reason) + 1)
                return False
        if not self.pinned:
            self.peer_address = address
            self.pinned = True
        return True

    def _handle(self, msg: Any, now: float) -> None:
        kind = msg.get_type()
        tel = self.telemetry
        if kind == "LOCAL_POSITION_NED" and not all(map(math.isfinite, (
                msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz))):
            # Proof of life, but not a position: never stored, never passed on.
            tel.message_time = now
            tel.invalid_estimate_time = now
            tel.invalid_estimates += 1
            return
        tel.message_time = now
        if msg.get_srcComponent() == self.component_id:
            _count_sequence(tel, msg.get_seq())
        if kind == "HEARTBEAT":
            if msg.get_srcComponent() == self.component_id:
                tel.heartbeat_time = now
                tel.autopilot = msg.autopilot
                tel.vehicle_type = msg.type
                tel.mode = px4.decode_custom_mode(msg.custom_mode)
                tel.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                tel.system_status = msg.system_status
        elif kind == "LOCAL_POSITION_NED":
            tel.position_ned = (msg.x, msg.y, msg.z)
            tel.velocity_ned = (msg.vx, msg.vy, msg.vz)
            tel.position_time = now
        elif kind == "EXTENDED_SYS_STATE":
            tel.landed_state = msg.landed_state
        elif kind == "COMMAND_ACK":
            self._handle_ack(msg)
        elif kind == "GPS_GLOBAL_ORIGIN":
            tel.gps_origin = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3)
        elif kind == "HOME_POSITION" and all(map(math.isfinite, (msg.x, msg.y, msg.z))):
            tel.home = ((msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3),
                        (msg.x, msg.y, msg.z))
        elif kind == "STATUSTEXT":
            text = self._texts.add(msg)
            if text is None:  # a chunk of a longer text: listeners get the whole one
                return
            tel.statustexts.append(text)
            if msg.severity <= mavlink.MAV_SEVERITY_WARNING:
                tel.warnings.append(text)
        elif kind in ("SYS_STATUS", "BATTERY_STATUS", "GPS_RAW_INT"):
            _health_message(tel, kind, msg)
        for callback in self.listeners:
            callback(self, msg, now)
        if self._waiters:
            self._check_waiters()

    def _handle_ack(self, msg: Any) -> None:
        # Only the pinned peer's packets get here (`_accept`); only a pending command counts.
        if msg.target_system not in (0, GCS_SYSTEM_ID):
            return
        now = time.monotonic()
        pending = self._pending.get(msg.command)
        echo = self._echoes.get(msg.command)
        if echo is not None and (now > echo[1] or msg.result == echo[0]):
            del self._echoes[msg.command]  # expired, or here it is
            if now <= echo[1]:  # the previous command's second ACK: not this one's answer
                self.duplicate_acks += 1
                return
        if pending is None or pending.future.done():
            self.duplicate_acks += 1  # PX4 ACKs DO_SET_MODE and REQUEST_MESSAGE twice
            return
        if msg.result == mavlink.MAV_RESULT_IN_PROGRESS:
            pending.sent_at = now  # keep waiting for the final result
            return
        if msg.command in px4.ACKED_TWICE:
            self._echoes[msg.command] = (int(msg.result), now + px4.DUPLICATE_ACK_WINDOW_S)
        pending.future.set_result(int(msg.result))

    def _check_waiters(self) -> None:
        keep = []
        for predicate, future in self._waiters:
            if future.done():
                continue
            if predicate(self.telemetry):
                future.set_result(None)
            else:
                keep.append((predicate, future))
        self._waiters = keep

    async def wait_for(self, predicate: Callable[[Telemetry], bool], timeout: float) -> bool:
        """Wait until `predicate(telemetry)` holds after some message; False on timeout."""
        if predicate(self.telemetry):
            return True
        future: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._waiters.append((predicate, future))
        try:
            await asyncio.wait_for(future, timeout)
            return True
        except TimeoutError:
            return False
        finally:
            if not future.done():
                future.cancel()

    def link_age(self, now: float | None = None) -> float:
        """Seconds since any message of this vehicle arrived (inf before the first)."""
        if self.telemetry.message_time is None:
            return math.inf
        return (time.monotonic() if now is None else now) - self.telemetry.message_time

    def heartbeat_age(self, now: float | None = None) -> float:
        """Seconds since the last HEARTBEAT (inf before the first)."""
        if self.telemetry.heartbeat_time is None:
            return math.inf
        return (time.monotonic() if now is None else now) - self.telemetry.heartbeat_time

    # ---------------------------------------------------------------- sending

    def pack(self, msg: Any) -> bytes:
        """`msg` encoded (and signed, with a key) for this vehicle."""
        if self.signing is not None:
            return self.signing.pack(msg, self.mav)
        return self.endpoint.pack(msg)

    def send(self, msg: Any) -> None:
        self.endpoint.send_bytes(self.system_id, self.pack(msg))

    def send_heartbeat(self) -> None:
        """The GCS HEARTBEAT (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)."""
        self.send(self.mav.heartbeat_encode(
            mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))

    def send_setup_signing(self, key: SigningKey, initial_timestamp: int) -> None:
        """SETUP_SIGNING with `key` (provisioning: only over a link you trust, and while the
        vehicle is disarmed; a vehicle that already has a key wants it signed with that)."""
        self.send(self.mav.setup_signing_encode(self.system_id, self.component_id,
                                                list(key.secret), initial_timestamp))

    def send_setpoint(self, setpoint: Setpoint, boot_ms: int) -> None:
        """One SET_POSITION_TARGET_LOCAL_NED to this vehicle."""
        self.send_packed(self.pack_setpoint(setpoint, boot_ms))

    def pack_setpoint(self, setpoint: Setpoint, boot_ms: int) -> bytes:
        """SET_POSITION_TARGET_LOCAL_NED for this vehicle, encoded ahead of its send."""
        fields = setpoint.fields(self.system_id, self.component_id, boot_ms)
        return self.pack(self.mav.set_position_target_local_ned_encode(**fields))

    def send_packed(self, buf: bytes) -> None:
        """Send a setpoint from `pack_setpoint`."""
        self.endpoint.send_bytes(self.system_id, buf)
        self.setpoints_sent += 1

    async def command(self, command: int, params: tuple[float, ...] = (), *,
                      timeout: float = 1.0, retries: int = 8) -> int:
        """Send COMMAND_LONG and return the final MAV_RESULT of its COMMAND_ACK.

        Resends (with `confirmation` counting up) when no ACK arrives within `timeout`;
        IN_PROGRESS extends the wait; a second ACK for the same command (PX4 sends two for
        DO_SET_MODE) is ignored, also when it arrives after a newer command with the same id
        went out (`px4.ACKED_TWICE`): it never answers that one. Raises `CommandError` when no
        ACK came after all retries.
        """
        p = (list(params) + [0.0] * 7)[:7]
        if command in self._pending and not self._pending[command].future.done():
            raise CommandError(self.vehicle_id, command, None,
                               f"command {command} already in flight")
        loop = asyncio.get_running_loop()
        for attempt in range(retries + 1):
            future: asyncio.Future[int] = loop.create_future()
            pending = _PendingCommand(command, future, time.monotonic())
            self._pending[command] = pending
            self.send(self.mav.command_long_encode(
                self.system_id, self.component_id, command, attempt, *p))
            try:
                while True:
                    remaining = pending.sent_at + timeout - time.monotonic()
                    if remaining <= 0:
                        break
                    try:
                        return await asyncio.wait_for(asyncio.shield(future), remaining)
                    except TimeoutError:
                        continue
            finally:
                # Cancelled (an abort stopping the flow) or done: this command no longer
                # waits, so the next one with the same id (the abort's disarm) may go out.
                future.cancel()
                if self._pending.get(command) is pending:
                    del self._pending[command]
        raise CommandError(self.vehicle_id, command, None,
                           f"no COMMAND_ACK for command {command} after {retries + 1} tries")

    async def request_message(self, message_id: int, timeout: float = 1.0) -> int:
        """MAV_CMD_REQUEST_MESSAGE for `message_id`; returns the MAV_RESULT."""
        return await self.command(mavlink.MAV_CMD_REQUEST_MESSAGE, (float(message_id),),
                                  timeout=timeout)


class LinkHub:
    """The endpoints of a fleet, their GCS heartbeats (1 Hz) and their vehicles.

    Use as ``async with LinkHub() as hub: link = hub.add(vehicle_id, url, system_id)``;
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
        while True:
            for i, link in enumerate(list(self.links.values())):
                link.send_heartbeat()
                if i % 10 == 9:  # a 100-vehicle round is milliseconds: let a tick through
                    await asyncio.sleep(0)
            for signing in self.signers.values():
                signing.reserve()
            await asyncio.sleep(self.heartbeat_period)

    async def close(self) -> None:
        if self._heartbeat_task is not None:
            self._heartbeat_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._heartbeat_task
            self._heartbeat_task = None
        for endpoint in self.endpoints.values():
            endpoint.close()
        await asyncio.sleep(0)  # transports release their sockets on the next loop turn
