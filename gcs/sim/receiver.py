"""What a mock vehicle does with one incoming UDP datagram before any handler sees it: PX4's
MavlinkReceiver path (``mavlink_receiver.cpp``, ``mavlink_main.cpp``,
``mavlink_sign_control.cpp``), step by step (`MavlinkIntake`).

1. **Partner.** PX4's UDP link sends to its configured remote until the first datagram
   arrives; that datagram's source becomes the link's partner (`_src_addr`) for good: PX4
   sets it only while ``get_client_source_initialized()`` is false, straight after
   ``recvfrom``, before anything is parsed or any signature checked, and nothing clears it
   (``mavlink start -t IP`` fixes it up front instead). So a rejected packet, or junk, takes
   the partner if it is the very first datagram the link hears; once the GCS has spoken, no
   packet from anyone else, accepted or not, moves the vehicle's replies
   (`gcs.sim.links.UdpLink.heard`).
2. **Framing and signature.** Every packet is framed and CRC-checked; with a key, one that is
   unsigned or signed with another key is rejected by the MAVLink library
   (MAVLINK_FRAMING_BAD_SIGNATURE, a parse error) unless its id is in PX4's allowlist
   (`gcs.wire.PX4_UNSIGNED_ACCEPTED`). A rejected packet is never decoded further, handled,
   ACKed or forwarded: its whole cost is the CRC (and the HMAC, if signed).
3. What is left goes to the vehicle's handlers (`gcs.sim.vehicle`).

The signature checks are pymavlink's, run with the vehicle's signing state; this module only
classifies and counts what they decided (`IntakeCounters`, one set per vehicle, all links).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gcs.sim.links import UdpLink
from gcs.wire import mavlink

__all__ = ["IntakeCounters", "MavlinkIntake"]

_IFLAG_SIGNED = mavlink.MAVLINK_IFLAG_SIGNED
_INVALID_SIGNATURE = "Invalid signature"


@dataclass
class IntakeCounters:
    """What one vehicle did with the packets it heard, on all its links."""

    datagrams: int = 0
    """Datagrams heard (after boot and the injected loss)."""
    from_others: int = 0
    """Of them, datagrams from an address other than their link's partner."""
    accepted: int = 0
    """Packets passed to the handlers (signed with the key, or unsigned and allowed)."""
    unsigned_allowed: int = 0
    """Of them, unsigned packets let through with a key set (PX4's allowlist: HEARTBEAT,
    RADIO_STATUS, ADSB_VEHICLE, COLLISION)."""
    rejected_unsigned: int = 0
    """Unsigned packets rejected because the vehicle has a key."""
    rejected_bad_signature: int = 0
    """Signed packets rejected: another key, altered, or replayed."""
    garbage: int = 0
    """Datagrams (or parts) that were no valid packet: bad CRC, truncated, junk."""

    @property
    def rejected(self) -> int:
        """Packets rejected by the signing rules."""
        return self.rejected_unsigned + self.rejected_bad_signature


class MavlinkIntake:
    """One mock vehicle's receiving end (see the module docstring): `signing` is pymavlink's
    signing state of the vehicle, whose key decides what is rejected."""

    def __init__(self, signing: Any) -> None:
        self.signing = signing
        self.counters = IntakeCounters()

    def receive(self, data: bytes, address: tuple[str, int], link: UdpLink) -> list[Any]:
        """The packets of one datagram from `address` on `link` that the vehicle accepts, in
        order. The link's first datagram ever latches its partner, whatever it holds (PX4
        does so before parsing); every packet then faces the signing rules."""
        counters = self.counters
        counters.datagrams += 1
        if link.partner is not None and address != link.partner:
            counters.from_others += 1
        link.heard(address)
        # A fresh parser per datagram (a packet never spans datagrams), with the vehicle's
        # signing state: pymavlink checks signatures and timestamps in `decode`.
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        parser.signing = self.signing
        unsigned_before = self.signing.unsigned_count
        try:
            found = parser.parse_buffer(data) or []
        except mavlink.MAVError:
            counters.garbage += 1
            return []
        accepted = []
        for msg in found:
            if msg.get_type() != "BAD_DATA":
                accepted.append(msg)
            elif str(msg.reason) == _INVALID_SIGNATURE:
                raw = bytes(msg.data)
                if len(raw) > 2 and raw[2] & _IFLAG_SIGNED:
                    counters.rejected_bad_signature += 1
                else:
                    counters.rejected_unsigned += 1
            else:
                counters.garbage += 1
        if len(parser.buf) > parser.buf_index:  # an incomplete packet at the end
            counters.garbage += 1
        counters.accepted += len(accepted)
        counters.unsigned_allowed += self.signing.unsigned_count - unsigned_before
        return accepted
