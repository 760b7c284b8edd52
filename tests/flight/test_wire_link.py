"""Wire-level facts of the GCS link: every message the GCS sends carries the next MAVLink
sequence number (signed or not), as pymavlink's own `send` would (`msg.pack` alone stamps them
all 0, which a receiver counting gaps for link quality reads as loss); chunked STATUSTEXTs are
joined."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs import wire
from gcs.flight.link.endpoints import UdpEndpoint
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.setpoints import Setpoint
from gcs.flight.link.signing import LinkSigning
from gcs.wire import mavlink, parse_datagram

VEHICLE = ("127.0.0.1", 14580)


def _sequence(packets: list[bytes]) -> list[int]:
    return [parse_datagram(buf).messages[0].get_seq() for buf in packets]


def test_wire_pack_advances_the_sequence_and_wraps() -> None:
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.seq = 254
    packets = [wire.pack(mav.heartbeat_encode(6, 8, 0, 0, 4), mav) for _ in range(3)]
    assert _sequence(packets) == [254, 255, 0]


@pytest.mark.parametrize("signed", [False, True], ids=["unsigned", "signed"])
def test_a_vehicle_link_numbers_heartbeats_commands_and_setpoints_in_order(
        signed: bool, tmp_path: Path) -> None:
    endpoint = UdpEndpoint("udpin:127.0.0.1:14999")  # never opened: packing needs no socket
    signing = LinkSigning(wire.new_key_file(tmp_path / "k.key")) if signed else None
    link = VehicleLink("uav1", endpoint, system_id=1, signing=signing)
    mav = link.mav
    packets = [
        link.pack(mav.heartbeat_encode(6, 8, 0, 0, 4)),
        link.pack(mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)),
        link.pack_setpoint(Setpoint((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0), 0),
    ]
    first = _sequence(packets)[0]
    assert _sequence(packets) == [first, (first + 1) % 256, (first + 2) % 256]
    assert all(bool(buf[2] & mavlink.MAVLINK_IFLAG_SIGNED) == signed for buf in packets)


def test_chunked_statustexts_are_joined_before_anyone_sees_them() -> None:
    """PX4 (and the mock) split a text over 50 bytes into chunks with one id; the link keeps
    and reports the whole text, and a plain text (id 0) passes as it is."""
    link = VehicleLink("uav1", UdpEndpoint("udpin:127.0.0.1:14998"), system_id=1)
    seen: list[str] = []
    link.listeners.append(lambda _link, msg, _now: seen.append(msg.get_type()))
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    whole = "Arming denied: Resolve system health failures first"  # 51 characters
    chunks = [whole[:50], whole[50:]]
    for seq, text in enumerate(chunks):
        msg = parse_datagram(wire.pack(mav.statustext_encode(2, text.encode(), 7, seq),
                                       mav)).messages[0]
        link.receive(msg, VEHICLE, 0.0)
    plain = parse_datagram(wire.pack(mav.statustext_encode(6, b"Takeoff detected"),
                                     mav)).messages[0]
    link.receive(plain, VEHICLE, 0.0)
    assert list(link.telemetry.statustexts) == [whole, "Takeoff detected"]
    assert seen == ["STATUSTEXT", "STATUSTEXT"]  # the first chunk alone reached nobody
    assert list(link.telemetry.warnings) == [whole]


def test_px4s_trailing_tab_is_not_part_of_the_text() -> None:
    """PX4 ends a status text it also reports as an event with a tab (so that a ground
    station showing events can hide the duplicate): "Connection to ground station lost\\t",
    and a long one's tab comes in its last chunk. The GCS shows and matches the text without
    it."""
    texts = wire.StatusTexts()
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)

    def statustext(text: str, ident: int = 0, seq: int = 0) -> object:
        return parse_datagram(wire.pack(mav.statustext_encode(4, text.encode(), ident, seq),
                                        mav)).messages[0]

    assert texts.add(statustext("Connection to ground station lost\t")) == \
        "Connection to ground station lost"
    whole = "Arming denied: Resolve system health failures first"
    assert texts.add(statustext(whole[:50], 9, 0)) is None
    assert texts.add(statustext(whole[50:] + "\t", 9, 1)) == whole
    assert texts.add(statustext("Takeoff detected")) == "Takeoff detected"
