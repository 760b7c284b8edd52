"""Every message the GCS sends carries the next MAVLink sequence number (signed or not), as
pymavlink's own `send` would: `msg.pack` alone stamps them all 0, which a receiver that counts
gaps (link quality, like our own health check) reads as loss."""

from __future__ import annotations

from gcs import wire
from gcs.flight.link import UdpEndpoint, VehicleLink
from gcs.wire import mavlink, parse_datagram


def _sequence(packets: list[bytes]) -> list[int]:
    return [parse_datagram(buf).messages[0].get_seq() for buf in packets]


def test_wire_pack_advances_the_sequence_and_wraps() -> None:
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.seq = 254
    packets = [wire.pack(mav.heartbeat_encode(6, 8, 0, 0, 4), mav) for _ in range(3)]
    assert _sequence(packets) == [254, 255, 0]


def test_a_vehicle_link_numbers_heartbeats_commands_and_setpoints_in_order() -> None:
    endpoint = UdpEndpoint("udpin:127.0.0.1:14999")  # never opened: packing needs no socket
    link = VehicleLink("uav1", endpoint, system_id=1)
    mav = link.mav
    packets = [
        link.pack(mav.heartbeat_encode(6, 8, 0, 0, 4)),
        link.pack(mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)),
        link.pack(mav.heartbeat_encode(6, 8, 0, 0, 4)),
    ]
    first = _sequence(packets)[0]
    assert _sequence(packets) == [first, (first + 1) % 256, (first + 2) % 256]
