"""One vehicle's MAVLink link (`VehicleLink`): which of its packets are admitted, its telemetry
and listeners, waits on that telemetry, and what the GCS sends it (commands, setpoints).

Admission: the *pinned peer* (source address + autopilot component) is fixed by the first
accepted packet, or up front by the fleet file's ``peer``; packets with the vehicle's system id
from any other address or component are dropped and counted (`SecurityCounters`), and nothing
is ever sent anywhere but the pinned address. With a signing key (`gcs.flight.link.signing`),
everything it sends is signed and every unsigned, wrongly signed or replayed packet is dropped
and counted. A packet the endpoint did not decode (an id outside `DECODED_IDS`) passes the same
check before its sequence number counts for link quality.

Commands: `command()` sends COMMAND_LONG and waits for a COMMAND_ACK from the pinned peer, for a
pending command only, with retries and duplicate-ACK tolerance. The sockets are
`gcs.flight.link.endpoints`; several links and their heartbeats are `gcs.flight.link.hub.LinkHub`.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from gcs.errors import CommandError
from gcs.flight.link.endpoints import Endpoint
from gcs.flight.link.interface import MessageHandler
from gcs.flight.link.setpoints import Setpoint
from gcs.flight.link.signing import LinkSigning
from gcs.flight.link.station import Clock
from gcs.flight.link.telemetry import Telemetry
from gcs.wire import GCS_COMPONENT_ID, GCS_SYSTEM_ID, PacketHeader, SigningKey, mavlink

__all__ = ["DECODED_IDS", "MAX_CLAIMANTS", "MessageCallback", "VehicleLink"]

MessageCallback = Callable[["VehicleLink", Any, float], None]
"""A listener: called with (link, message, receive time) for every message passed on."""

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
    _m.MAVLINK_MSG_ID_TIMESYNC,  # the answers to the station's, for latency
    # the mission protocol, for the geofence upload and read-back
    # (`gcs.flight.procedure.fence_upload`)
    _m.MAVLINK_MSG_ID_MISSION_REQUEST_INT, _m.MAVLINK_MSG_ID_MISSION_REQUEST,
    _m.MAVLINK_MSG_ID_MISSION_ACK, _m.MAVLINK_MSG_ID_MISSION_COUNT,
    _m.MAVLINK_MSG_ID_MISSION_ITEM_INT,
    # the parameter protocol, for the link-loss failsafe (`gcs.flight.procedure.failsafe`)
    _m.MAVLINK_MSG_ID_PARAM_VALUE,
})

#: How many other claimants of one vehicle are remembered (enough to name them; bounded).
MAX_CLAIMANTS = 4


@dataclass
class _PendingCommand:
    """A COMMAND_LONG waiting for its COMMAND_ACK."""

    command: int
    future: asyncio.Future[int]
    sent_at: float
    clock: Clock
    """The clock `sent_at` and the try's timeout are on."""


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
        self.peer_given = peer is not None
        """Whether the peer was pinned up front (the fleet file's ``peer``)."""
        self.claimants: list[Any] = []
        """Other addresses that claimed this unsigned vehicle (its system id and component)
        after first contact pinned one: two sources for one vehicle, which the connect step
        refuses (`other_claimants`). At most `MAX_CLAIMANTS` are kept."""
        self.mav = endpoint.mav
        """This vehicle's packer: the endpoint's, or its own sharing the key's signing state."""
        if signing is not None:
            self.mav = mavlink.MAVLink(None, srcSystem=GCS_SYSTEM_ID,
                                       srcComponent=GCS_COMPONENT_ID)
            self.mav.signing = signing.state
        self.telemetry = Telemetry()
        self.listeners: list[MessageCallback] = []
        """Called with (link, message, receive time) for every message of this vehicle."""
        self._pending: dict[int, _PendingCommand] = {}
        self._echoes: dict[int, tuple[int, float]] = {}
        """command -> (result, until): the second ACK still due for a command PX4 ACKs twice."""
        self._waiters: list[tuple[Callable[[Telemetry], bool], asyncio.Future[None]]] = []
        self.duplicate_acks = 0
        self.setpoints_sent = 0
        self.dropped_from: dict[str, tuple[Any, int]] = {}
        """Security counter name -> (address, component) of the latest packet dropped for
        it: what a connect that heard nothing it could admit reports (`drop_diagnosis`)."""
        endpoint.register(self)

    @contextlib.contextmanager
    def listening(self, handler: MessageHandler) -> Iterator[None]:
        """`handler` gets (message, receive time) for every message of this vehicle inside
        the ``with`` block: a listener for as long as a procedure step waits on it."""
        def listener(_link: VehicleLink, msg: Any, now: float) -> None:
            handler(msg, now)

        self.listeners.append(listener)
        try:
            yield
        finally:
            self.listeners.remove(listener)

    # ---------------------------------------------------------------- receiving

    def receive(self, msg: Any, address: Any, now: float) -> None:
        """A decoded packet with this vehicle's system id: handled if it is admitted."""
        if self._admit(msg.get_srcComponent(), address, lambda signing: signing.verify(msg)):
            self.handle(msg, now)

    def receive_skipped(self, header: PacketHeader, packet: bytes, address: Any) -> None:
        """A packet the endpoint did not decode (an id not read, or one `refuses` drops): if
        admitted, it counts for link quality (not as proof of life: that takes a decoded
        message); else only a security counter moves."""
        if self._admit(header.component, address,
                       lambda signing: signing.verify_packet(packet, header.system,
                                                             header.component)):
            self.telemetry.skipped += 1
            self.telemetry.count_sequence(header.seq)

    def refuses(self, header: PacketHeader, address: Any) -> bool:
        """Whether `_admit` drops a packet with `header` from `address` whatever its payload:
        another address than the pinned peer, another component, or unsigned while this
        vehicle has a key. The endpoint asks before decoding, so hostile traffic costs a
        header check; the drop is then counted by `receive_skipped`."""
        if self.pinned and address != self.peer_address:
            return True
        if header.component != self.component_id:
            return True
        return self.signing is not None and not header.signed

    def _admit(self, component: int, address: Any,
               verify: Callable[[LinkSigning], str | None]) -> bool:
        """Whether a packet from `component` at `address` whose signature `verify` checks
        (None: good; else the security counter to raise) is from the pinned peer and, with a
        key, correctly signed and new; the first admitted packet pins the peer."""
        counters = self.telemetry.security
        if self.pinned and address != self.peer_address:
            counters.foreign_source += 1
            self.dropped_from["foreign_source"] = (address, component)
            if (not self.peer_given and self.signing is None and component == self.component_id
                    and address not in self.claimants and len(self.claimants) < MAX_CLAIMANTS):
                self.claimants.append(address)
            return False
        if component != self.component_id:
            counters.other_component += 1
            self.dropped_from["other_component"] = (address, component)
            return False
        if self.signing is not None:
            reason = verify(self.signing)
            if reason is not None:
                counters.count(reason)
                self.dropped_from[reason] = (address, component)
                return False
        if not self.pinned:
            self.peer_address = address
            self.pinned = True
        return True

    def handle(self, msg: Any, now: float) -> None:
        """An admitted message: into the telemetry, to a pending command, to the listeners."""
        if not self.telemetry.update(msg, now, self.component_id):
            return
        if msg.get_type() == "COMMAND_ACK":
            self._handle_ack(msg)
        for callback in self.listeners:
            callback(self, msg, now)
        if self._waiters:
            self._check_waiters()

    def _handle_ack(self, msg: Any) -> None:
        """A COMMAND_ACK: the answer of the pending command with its id, or a duplicate."""
        # Only the pinned peer's packets get here (`_admit`); only a pending command counts.
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
            pending.sent_at = pending.clock()  # keep waiting for the final result
            return
        kind = self.telemetry.flown_by
        if msg.command in kind.acked_twice:
            self._echoes[msg.command] = (int(msg.result), now + kind.duplicate_ack_window_s)
        pending.future.set_result(int(msg.result))

    def _check_waiters(self) -> None:
        """Wake every `wait_for` whose predicate now holds."""
        keep = []
        for predicate, future in self._waiters:
            if future.done():
                continue
            if predicate(self.telemetry):
                future.set_result(None)
            else:
                keep.append((predicate, future))
        self._waiters = keep

    async def wait_for(self, predicate: Callable[[Telemetry], bool], timeout: float, *,
                       clock: Clock | None = None) -> bool:
        """Wait until `predicate(telemetry)` holds after some message; False on timeout.
        `timeout` is on `clock` (monotonic time unless given; `StationStalls.clock` makes the
        station's own stalls not use it up)."""
        if predicate(self.telemetry):
            return True
        now = clock or time.monotonic
        deadline = now() + timeout
        future: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._waiters.append((predicate, future))
        try:
            while (remaining := deadline - now()) > 0:
                try:
                    await asyncio.wait_for(asyncio.shield(future), remaining)
                    return True
                except TimeoutError:
                    continue
            return predicate(self.telemetry)
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
        """`msg` to this vehicle's pinned peer."""
        self.endpoint.send_bytes(self.system_id, self.pack(msg))

    def send_heartbeat(self) -> None:
        """The GCS HEARTBEAT (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)."""
        self.send(self.mav.heartbeat_encode(
            mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))

    def send_timesync(self) -> None:
        """A TIMESYNC request (tc1 0, ts1 the station's clock in ns): its answer gives the
        round trip (`gcs.flight.link.quality.Timing`)."""
        ts1 = self.telemetry.quality.timing.request(time.monotonic_ns())
        self.send(self.mav.timesync_encode(0, ts1))

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
                      timeout: float = 1.0, retries: int = 8,
                      clock: Clock | None = None) -> int:
        """Send COMMAND_LONG and return the final MAV_RESULT of its COMMAND_ACK.

        Resends (with `confirmation` counting up) when no ACK arrives within `timeout`;
        IN_PROGRESS extends the wait; a second ACK for the same command (PX4 sends two for
        DO_SET_MODE) is ignored, also when it arrives after a newer command with the same id
        went out (`Autopilot.acked_twice`): it never answers that one. Raises `CommandError` when no
        ACK came after all retries. Each try's `timeout` is on `clock` (monotonic time unless
        given; with `StationStalls.clock` a stall of the station does not use a try up).
        """
        p = (list(params) + [0.0] * 7)[:7]
        if command in self._pending and not self._pending[command].future.done():
            raise CommandError(self.vehicle_id, command, None,
                               f"command {command} already in flight")
        loop = asyncio.get_running_loop()
        now = clock or time.monotonic
        for attempt in range(retries + 1):
            future: asyncio.Future[int] = loop.create_future()
            pending = _PendingCommand(command, future, now(), now)
            self._pending[command] = pending
            self.send(self.mav.command_long_encode(
                self.system_id, self.component_id, command, attempt, *p))
            try:
                while True:
                    remaining = pending.sent_at + timeout - now()
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

    async def request_message(self, message_id: int, timeout: float = 1.0, *,
                              clock: Clock | None = None) -> int:
        """MAV_CMD_REQUEST_MESSAGE for `message_id`; returns the MAV_RESULT."""
        return await self.command(mavlink.MAV_CMD_REQUEST_MESSAGE, (float(message_id),),
                                  timeout=timeout, clock=clock)

