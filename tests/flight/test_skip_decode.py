"""Dropping unread message ids before decoding (`Endpoint.decode_ids`, `gcs.wire.peek_packet`):
skipped packets are counted, never garbage, never loss, and a spoofed one changes nothing.

Datagrams go straight into an endpoint's receive callback (`UdpEndpoint.received`, what
asyncio calls), so every count is exact."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from gcs.flight.link.endpoints import UdpEndpoint
from gcs.flight.link.link import DECODED_IDS, VehicleLink
from gcs.flight.link.signing import LinkSigning
from gcs.wire import mavlink, new_key_file, pack, peek_packet, signing_timestamp

VEHICLE = ("127.0.0.1", 14580)
ELSEWHERE = ("127.0.0.1", 14999)


class Sender:
    """Vehicle 1's encoder: counting sequence numbers, optionally signing."""

    def __init__(self, key: bytes | None = None, component: int = 1) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=component)
        if key is not None:
            self.mav.signing.secret_key = key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.timestamp = signing_timestamp(time.time())

    def attitude(self) -> bytes:
        return pack(self.mav.attitude_encode(0, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0), self.mav)

    def position(self, x: float = 1.0) -> bytes:
        return pack(self.mav.local_position_ned_encode(0, x, 2.0, -3.0, 0, 0, 0), self.mav)

    def heartbeat(self) -> bytes:
        return pack(self.mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR,
                                              mavlink.MAV_AUTOPILOT_PX4, 0, 0, 0), self.mav)


def _endpoint(signing: LinkSigning | None = None) -> tuple[UdpEndpoint, VehicleLink, list[str]]:
    endpoint = UdpEndpoint("udpin:127.0.0.1:9", DECODED_IDS)  # never opened: no socket
    link = VehicleLink("v", endpoint, 1, 1, signing=signing, peer=VEHICLE)
    seen: list[str] = []
    link.listeners.append(lambda _l, m, _t: seen.append(m.get_type()))
    return endpoint, link, seen


def test_peek_reads_one_whole_valid_packet_only() -> None:
    s = Sender()
    buf = s.attitude()
    header = peek_packet(buf)
    assert header is not None
    assert (header.msg_id, header.system, header.component, header.signed) == (
        mavlink.MAVLINK_MSG_ID_ATTITUDE, 1, 1, False)
    assert peek_packet(buf + s.attitude()) is None  # two packets: decoded in full
    assert peek_packet(buf[:-1]) is None  # truncated
    corrupt = bytearray(buf)
    corrupt[12] ^= 0xFF
    assert peek_packet(bytes(corrupt)) is None  # bad CRC
    assert peek_packet(b"\xfd\xff\x00") is None
    odd = bytearray(buf)
    odd[2] |= 0x02  # an incompatibility flag this dialect does not know
    assert peek_packet(bytes(odd)) is None
    from pymavlink.dialects.v10 import common as mavlink1

    v1 = mavlink1.MAVLink(None, srcSystem=7, srcComponent=1)
    raw = v1.attitude_encode(0, 0, 0, 0, 0, 0, 0).pack(v1)
    assert raw[0] == 0xFE  # MAVLink 1: its header is read too
    header = peek_packet(raw)
    assert header is not None
    assert (header.msg_id, header.system, header.signed) == (mavlink.MAVLINK_MSG_ID_ATTITUDE,
                                                             7, False)
    assert peek_packet(raw[:-2] + bytes(2)) is None


def test_skipped_ids_count_for_link_quality_not_as_garbage_or_loss() -> None:
    endpoint, link, seen = _endpoint()
    s = Sender()
    for i in range(300):
        endpoint.received(s.attitude(), VEHICLE)
        if i % 10 == 0:
            endpoint.received(s.position(float(i)), VEHICLE)
    tel = link.telemetry
    assert tel.skipped == 300 and endpoint.skipped == 300
    assert seen == ["LOCAL_POSITION_NED"] * 30  # only what is decoded reaches listeners
    assert tel.position_ned == (290.0, 2.0, -3.0)
    assert tel.seq_received == 330 and tel.seq_lost == 0  # wraps past 255 twice: no loss
    assert endpoint.garbage_datagrams == 0 and tel.security.total == 0
    assert endpoint.messages_received == 330

    # real loss is still seen when the lost packets sit among skipped ones
    for i in range(51):  # a loss shows with the next packet that arrives
        buf = s.attitude() if i % 2 else s.position()
        if i % 5 != 4:  # lose every fifth packet on the way
            endpoint.received(buf, VEHICLE)
    assert tel.seq_lost == 10


def test_garbage_of_a_skipped_id_is_still_garbage() -> None:
    endpoint, link, _ = _endpoint()
    s = Sender()
    corrupt = bytearray(s.attitude())
    corrupt[14] ^= 0x55
    endpoint.received(bytes(corrupt), VEHICLE)
    endpoint.received(s.attitude()[:-3], VEHICLE)
    assert endpoint.garbage_datagrams == 2 and endpoint.skipped == 0
    assert link.telemetry.skipped == 0 and link.telemetry.seq_received == 0


def test_a_spoofed_skipped_packet_changes_nothing() -> None:
    endpoint, link, _ = _endpoint()
    s = Sender()
    endpoint.received(s.position(), VEHICLE)
    tel = link.telemetry
    before = (tel.seq_received, tel.seq_lost, tel.last_seq, tel.message_time, tel.skipped)
    spoofer = Sender()
    spoofer.mav.seq = 100  # a jump that would read as 98 lost messages if it counted
    endpoint.received(spoofer.attitude(), ELSEWHERE)  # another address
    other = Sender(component=42)
    other.mav.seq = 100
    endpoint.received(other.attitude(), VEHICLE)  # another component
    assert (tel.seq_received, tel.seq_lost, tel.last_seq, tel.message_time, tel.skipped) == \
        before
    assert tel.security.foreign_source == 1 and tel.security.other_component == 1


def test_signed_link_verifies_skipped_packets(tmp_path: Path) -> None:
    key = new_key_file(tmp_path / "k.key")
    endpoint, link, _ = _endpoint(LinkSigning(key))
    tel = link.telemetry
    good = Sender(key.secret)
    endpoint.received(good.position(), VEHICLE)
    endpoint.received(good.attitude(), VEHICLE)
    assert tel.skipped == 1 and tel.seq_received == 2 and tel.security.total == 0
    replay = good.attitude()
    endpoint.received(replay, VEHICLE)
    endpoint.received(replay, VEHICLE)  # the same signed packet again
    assert tel.security.replayed == 1
    unsigned = Sender()
    unsigned.mav.seq = 200  # would read as a big loss if it counted
    endpoint.received(unsigned.attitude(), VEHICLE)  # from the pinned address, unsigned
    wrong = Sender(bytes(32))
    wrong.mav.seq = 60
    endpoint.received(wrong.attitude(), VEHICLE)
    assert tel.security.unsigned == 1 and tel.security.bad_signature == 1
    assert tel.skipped == 2 and tel.seq_received == 3 and tel.seq_lost == 0
    # decoded packets still go through the full check: an unsigned position is refused
    endpoint.received(unsigned.position(9.0), VEHICLE)
    assert tel.position_ned == (1.0, 2.0, -3.0) and tel.security.unsigned == 2


def test_without_decode_ids_everything_is_decoded() -> None:
    endpoint = UdpEndpoint("udpin:127.0.0.1:9")
    link = VehicleLink("v", endpoint, 1, 1, peer=VEHICLE)
    seen: list[Any] = []
    link.listeners.append(lambda _l, m, _t: seen.append(m.get_type()))
    s = Sender()
    endpoint.received(s.attitude(), VEHICLE)
    assert seen == ["ATTITUDE"] and endpoint.skipped == 0 and link.telemetry.skipped == 0


def test_an_unpinned_vehicle_is_pinned_by_a_decoded_packet_only() -> None:
    endpoint = UdpEndpoint("udpin:127.0.0.1:9", DECODED_IDS)
    link = VehicleLink("v", endpoint, 1, 1)
    s = Sender()
    endpoint.received(s.attitude(), VEHICLE)  # before pinning: decoded, pins
    assert link.pinned and link.peer_address == VEHICLE and endpoint.skipped == 0
    endpoint.received(s.attitude(), VEHICLE)
    assert endpoint.skipped == 1
    unknown = mavlink.MAVLink(None, srcSystem=9, srcComponent=1)
    endpoint.received(pack(unknown.attitude_encode(0, 0, 0, 0, 0, 0, 0), unknown), VEHICLE)
    assert endpoint.dropped_unknown == 1


def _command(sender: Sender) -> bytes:
    """A COMMAND_LONG (a decoded id) from `sender`: NAV_LAND to vehicle 1."""
    return pack(sender.mav.command_long_encode(1, 1, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0,
                                               0, 0, 0), sender.mav)


def test_refused_packets_are_never_decoded(tmp_path: Path, monkeypatch: Any) -> None:
    """Hostile traffic of ids the link reads (positions, heartbeats, commands) from another
    address, another component, or unsigned while a key is set is judged on its header: the
    security counters move exactly as a full decode would make them, and nothing is decoded;
    the vehicle's own signed traffic is still decoded and admitted."""
    import gcs.flight.link.endpoints as endpoints

    key = new_key_file(tmp_path / "k.key")
    endpoint, link, seen = _endpoint(LinkSigning(key))
    good = Sender(key.secret)
    endpoint.received(good.position(5.0), VEHICLE)
    decoded = []
    real_parse = endpoints.parse_datagram
    monkeypatch.setattr(endpoints, "parse_datagram",
                        lambda data: decoded.append(data) or real_parse(data))
    signed_elsewhere = Sender(key.secret)
    unsigned = Sender()
    other_component = Sender(key.secret, component=42)
    for _ in range(10):
        endpoint.received(signed_elsewhere.position(9.0), ELSEWHERE)
        endpoint.received(_command(unsigned), VEHICLE)
        endpoint.received(unsigned.heartbeat(), VEHICLE)
        endpoint.received(other_component.position(9.0), VEHICLE)
    assert decoded == []
    assert endpoint.refused == 40 and endpoint.messages_received == 41
    security = link.telemetry.security
    assert (security.foreign_source, security.unsigned, security.other_component) == (
        10, 20, 10)
    assert link.dropped_from["unsigned"] == (VEHICLE, 1)
    assert link.telemetry.position_ned == (5.0, 2.0, -3.0)
    endpoint.received(good.position(6.0), VEHICLE)  # the vehicle's own: decoded, admitted
    assert len(decoded) == 1 and link.telemetry.position_ned == (6.0, 2.0, -3.0)
    assert seen == ["LOCAL_POSITION_NED", "LOCAL_POSITION_NED"]
