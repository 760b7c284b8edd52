"""The mock's receiving end as PX4's (`gcs.sim.receiver`): a link's partner latched by its
first datagram, whatever it holds, and never moved; the signing rules with PX4's unsigned
allowlist; every rejection counted by kind. Datagrams go straight in (no sockets)."""

from __future__ import annotations

import asyncio
import time
from typing import cast

from gcs.sim.links import UdpLink
from gcs.sim.receiver import MavlinkIntake
from gcs.sim.signing import install_key
from gcs.wire import mavlink, pack, signing_timestamp

KEY = bytes(range(32))
GCS = ("127.0.0.1", 14540)
CONFIGURED = ("127.0.0.1", 14540)
ATTACKER = ("127.0.0.1", 40001)


def _sender(key: bytes | None, system: int = 255, component: int = 190) -> mavlink.MAVLink:
    mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = signing_timestamp(time.time())
    return mav


def _land(mav: mavlink.MAVLink) -> bytes:
    return pack(mav.command_long_encode(1, 1, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0),
                mav)


def _heartbeat(mav: mavlink.MAVLink) -> bytes:
    return pack(mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                     mavlink.MAV_STATE_ACTIVE), mav)


def _intake(key: bytes | None = KEY) -> tuple[MavlinkIntake, UdpLink]:
    """A vehicle's intake with `key`, and its offboard link (no socket: nothing is sent)."""
    state = mavlink.MAVLink(None).signing
    install_key(state, key)
    link = UdpLink("offboard", cast(asyncio.DatagramTransport, None), CONFIGURED)
    return MavlinkIntake(state), link


def test_a_rejected_first_packet_still_takes_the_partner_for_good() -> None:
    """PX4 latches its partner right after recvfrom, before any signature check: the
    attacker's unsigned LAND is rejected, yet the vehicle answers the attacker from then
    on, and the GCS's signed packets that follow are accepted but do not move it back."""
    intake, link = _intake()
    assert link.address == CONFIGURED and link.partner is None
    assert intake.receive(_land(_sender(None)), ATTACKER, link) == []
    assert link.address == ATTACKER
    gcs = _sender(KEY)
    [msg] = intake.receive(_land(gcs), GCS, link)
    assert msg.get_type() == "COMMAND_LONG"
    assert link.address == ATTACKER
    c = intake.counters
    assert (c.datagrams, c.from_others, c.accepted, c.rejected_unsigned) == (2, 1, 1, 1)


def test_once_the_gcs_spoke_first_nobody_moves_the_partner() -> None:
    """Rejected commands and PX4's allowlisted unsigned HEARTBEAT from another address are
    counted, and the replies keep going to the GCS."""
    intake, link = _intake()
    gcs = _sender(KEY)
    assert len(intake.receive(_heartbeat(gcs), GCS, link)) == 1
    attacker = _sender(None, system=245)
    for _ in range(40):
        assert intake.receive(_land(attacker), ATTACKER, link) == []
    [hb] = intake.receive(_heartbeat(attacker), ATTACKER, link)  # accepted unsigned, as PX4
    assert hb.get_type() == "HEARTBEAT" and hb.get_srcSystem() == 245
    wrong_key = _sender(bytes(reversed(KEY)))
    assert intake.receive(_land(wrong_key), ATTACKER, link) == []
    assert link.address == GCS
    c = intake.counters
    assert (c.rejected_unsigned, c.rejected_bad_signature, c.rejected) == (40, 1, 41)
    assert (c.unsigned_allowed, c.accepted, c.from_others, c.garbage) == (1, 2, 42, 0)


def test_without_a_key_everything_well_formed_is_accepted_and_junk_is_garbage() -> None:
    """Junk counts as garbage, but as the first datagram it still takes the partner."""
    intake, link = _intake(None)
    assert intake.receive(b"hello, vehicle", ATTACKER, link) == []  # junk, yet the first
    assert link.address == ATTACKER
    other, link2 = _intake(None)
    assert len(other.receive(_land(_sender(None)), GCS, link2)) == 1
    assert other.receive(b"\xfd\xff\x00", GCS, link2) == []
    assert other.receive(b"hello, vehicle", ATTACKER, link2) == []
    c = other.counters
    assert (c.accepted, c.rejected, c.garbage, c.from_others) == (1, 0, 2, 1)
    assert link2.address == GCS
