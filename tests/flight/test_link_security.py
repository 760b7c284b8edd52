"""The GCS link's security, packet by packet on real loopback sockets: per-datagram parsing,
pinned peers, ACKs, non-finite telemetry, signing (unsigned, wrong key, replay) and the signing
timestamp across restarts.

No test sleeps for a fixed time: each waits for the count or state the packets it sent must
produce (`_until`), and checks what must not have happened once that has."""

from __future__ import annotations

import asyncio
import math
import os
import socket
import stat
import time
from pathlib import Path
from typing import Any

import pytest

from gcs.autopilot import px4
from gcs.errors import LinkError, VehicleTimeout
from gcs.fleet.fleetfile import FleetSpec, VehicleSpec
from gcs.flight.link import signing as signing_module
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.signing import RESERVE, LinkSigning, timestamp_path
from gcs.flight.procedure.vehicle import connect
from gcs.sim import MockFleet
from gcs.wire import (
    GCS_SYSTEM_ID,
    KeyFileError,
    load_key,
    mavlink,
    new_key_file,
    parse_datagram,
    signing_timestamp,
)
from tests.flight.support import free_port_block, mock_ports
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(30)


class Peer:
    """A UDP socket speaking as system `system_id` (the vehicle, or someone pretending)."""

    def __init__(self, system_id: int = 1, key: bytes | None = None,
                 timestamp: int | None = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()
        self.mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=1)
        if key is not None:
            self.mav.signing.secret_key = key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.timestamp = timestamp or signing_timestamp(time.time())

    def heartbeat(self, mode: px4.Px4Mode = px4.HOLD, armed: bool = False) -> bytes:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        return self.mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                         base, mode.custom_mode,
                                         mavlink.MAV_STATE_STANDBY).pack(self.mav)

    def position(self, x: float = 1.0) -> bytes:
        return self.mav.local_position_ned_encode(0, x, 2.0, -3.0, 0.0, 0.0, 0.0).pack(self.mav)

    def ack(self, command: int, result: int = mavlink.MAV_RESULT_ACCEPTED) -> bytes:
        return self.mav.command_ack_encode(command, result, 0, 0, GCS_SYSTEM_ID,
                                           190).pack(self.mav)

    def send(self, buf: bytes, port: int) -> None:
        self.sock.sendto(buf, ("127.0.0.1", port))

    def received(self) -> list[Any]:
        """Every message that has arrived since the last call."""
        out: list[Any] = []
        while True:
            try:
                data = self.sock.recv(4096)
            except BlockingIOError:
                return out
            out.extend(parse_datagram(data).messages)

    async def receive_until(self, kind: str) -> list[Any]:
        """Every message that arrives up to and including the first of type `kind`."""
        out: list[Any] = []

        def arrived() -> bool:
            out.extend(self.received())
            return any(m.get_type() == kind for m in out)

        await until(arrived, timeout=10.0, poll=0.001)
        return out

    def close(self) -> None:
        self.sock.close()


def _run(coro: Any) -> Any:
    return asyncio.run(coro)


def test_parse_datagram_counts_garbage_and_keeps_the_next_datagram() -> None:
    real = Peer().heartbeat()
    assert parse_datagram(b"\xfd\xff\x00").garbage_bytes == 3
    parsed = parse_datagram(real)
    assert [m.get_type() for m in parsed.messages] == ["HEARTBEAT"] and parsed.garbage_bytes == 0
    junk = parse_datagram(b"\x00\x01\x02garbage")
    assert junk.messages == [] and junk.garbage_bytes > 0


def test_truncated_headers_cannot_desynchronise_a_vehicle() -> None:
    """3-byte truncated headers between every real packet swallow none of them."""
    async def main() -> None:
        port = free_port_block(1)
        vehicle, attacker = Peer(), Peer(system_id=7)
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", f"udpin:127.0.0.1:{port}", 1)
                positions = []
                link.listeners.append(lambda _l, m, _t: positions.append(m.get_type()))
                for i in range(20):
                    attacker.send(b"\xfd\xff\x00", port)
                    vehicle.send(vehicle.position(float(i)), port)
                await until(lambda: link.endpoint.garbage_datagrams == 20
                            and len(positions) == 20, timeout=10.0, poll=0.001)
                assert positions.count("LOCAL_POSITION_NED") == 20  # none swallowed
                assert link.telemetry.position_ned == (19.0, 2.0, -3.0)
                assert link.endpoint.garbage_datagrams == 20
        finally:
            vehicle.close()
            attacker.close()

    _run(main())


def test_peer_is_pinned_spoofs_dropped_counted_and_never_sent_to() -> None:
    async def main() -> None:
        port = free_port_block(1)
        vehicle, spoofer = Peer(), Peer()
        try:
            async with LinkHub(heartbeat_period=0.05) as hub:
                link = await hub.add("uav1", f"udpin:127.0.0.1:{port}", 1)
                vehicle.send(vehicle.heartbeat(px4.OFFBOARD, armed=True), port)
                await until(lambda: link.pinned, timeout=10.0, poll=0.001)
                assert link.peer_address == vehicle.address
                assert link.telemetry.mode == px4.OFFBOARD
                # spoofed HEARTBEAT (POSCTL, disarmed), positions, and the hijack's SYSTEM_TIME
                for _ in range(10):
                    spoofer.send(spoofer.heartbeat(px4.POSITION), port)
                    spoofer.send(spoofer.position(99.0), port)
                    spoofer.send(spoofer.mav.system_time_encode(0, 0).pack(spoofer.mav), port)
                await until(lambda: link.telemetry.security.foreign_source == 30,
                            timeout=10.0, poll=0.001)
                assert link.telemetry.mode == px4.OFFBOARD and link.telemetry.armed
                assert link.telemetry.position_ned is None
                assert link.peer_address == vehicle.address
                vehicle.received()
                # a heartbeat round and a setpoint, both sent after every spoof was handled
                await vehicle.receive_until("HEARTBEAT")
                link.send_setpoint(_setpoint(), 0)
                await vehicle.receive_until("SET_POSITION_TARGET_LOCAL_NED")
                assert spoofer.received() == []  # nothing ever goes to the spoofer
        finally:
            vehicle.close()
            spoofer.close()

    _run(main())


def test_peer_from_the_fleet_file_is_pinned_before_first_contact() -> None:
    async def main() -> None:
        port = free_port_block(1)
        vehicle, early = Peer(), Peer()
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", f"udpin:127.0.0.1:{port}", 1,
                                     peer=vehicle.address)
                early.send(early.heartbeat(), port)  # first to speak, but not the pinned peer
                await until(lambda: link.telemetry.security.foreign_source == 1,
                            timeout=10.0, poll=0.001)
                assert link.telemetry.heartbeat_time is None and link.telemetry.seq_received == 0
                vehicle.send(vehicle.heartbeat(), port)
                await until(lambda: link.telemetry.heartbeat_time is not None,
                            timeout=10.0, poll=0.001)
                assert link.peer_address == vehicle.address
        finally:
            vehicle.close()
            early.close()

    _run(main())


def test_acks_count_only_from_the_pinned_peer_for_a_pending_command() -> None:
    async def main() -> None:
        port = free_port_block(1)
        vehicle, spoofer = Peer(), Peer()
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", f"udpin:127.0.0.1:{port}", 1)
                vehicle.send(vehicle.heartbeat(), port)
                await until(lambda: link.pinned, timeout=10.0, poll=0.001)
                land = mavlink.MAV_CMD_NAV_LAND
                # an ACK for a command nobody sent changes nothing
                vehicle.send(vehicle.ack(land), port)
                await until(lambda: link.duplicate_acks == 1, timeout=10.0, poll=0.001)
                # one try, with a timeout no busy machine reaches: only an ACK ends it
                task = asyncio.create_task(link.command(land, timeout=30.0, retries=0))
                sent = await vehicle.receive_until("COMMAND_LONG")
                assert [m.command for m in sent if m.get_type() == "COMMAND_LONG"] == [land]
                spoofer.send(spoofer.ack(land), port)  # the spoofer's ACCEPTED is not an answer
                await until(lambda: link.telemetry.security.foreign_source == 1,
                            timeout=10.0, poll=0.001)
                assert not task.done()
                vehicle.send(vehicle.ack(land, mavlink.MAV_RESULT_DENIED), port)
                assert await task == mavlink.MAV_RESULT_DENIED
                assert link.telemetry.security.foreign_source == 1 and link.duplicate_acks == 1
        finally:
            vehicle.close()
            spoofer.close()

    _run(main())


def test_non_finite_position_is_never_stored_and_is_timestamped() -> None:
    async def main() -> None:
        port = free_port_block(1)
        vehicle = Peer()
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", f"udpin:127.0.0.1:{port}", 1)
                seen: list[str] = []
                link.listeners.append(lambda _l, m, _t: seen.append(m.get_type()))
                vehicle.send(vehicle.position(1.0), port)
                await until(lambda: link.telemetry.position_ned is not None,
                            timeout=10.0, poll=0.001)
                for bad in (math.nan, math.inf):
                    vehicle.send(vehicle.mav.local_position_ned_encode(
                        0, bad, 0.0, 0.0, 0.0, 0.0, 0.0).pack(vehicle.mav), port)
                vehicle.send(vehicle.mav.local_position_ned_encode(
                    0, 1.0, 0.0, 0.0, 0.0, math.nan, 0.0).pack(vehicle.mav), port)
                tel = link.telemetry
                await until(lambda: tel.invalid_estimates == 3, timeout=10.0, poll=0.001)
                assert tel.position_ned == (1.0, 2.0, -3.0)  # the last finite one
                assert tel.invalid_estimate_time is not None and tel.position_time is not None
                assert tel.invalid_estimate_time >= tel.position_time  # the bad ones' time
                assert seen == ["LOCAL_POSITION_NED"]  # listeners (the record) never see NaN
        finally:
            vehicle.close()

    _run(main())


def _setpoint() -> Any:
    from gcs.flight.link.setpoints import Setpoint
    return Setpoint((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)


# ---------------------------------------------------------------------------- signing


def test_key_files_are_private_and_never_overwritten(tmp_path: Path) -> None:
    path = tmp_path / "fleet.key"
    key = new_key_file(path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert len(key.secret) == 32 and load_key(path) == key
    assert key.secret.hex() not in repr(key) and key.secret.hex() not in str(key)
    with pytest.raises(KeyFileError, match="already exists"):
        new_key_file(path)
    os.chmod(path, 0o640)
    with pytest.raises(KeyFileError, match="group/others"):
        load_key(path)
    bad = tmp_path / "bad.key"
    bad.write_text("abcd\n")
    os.chmod(bad, 0o600)
    with pytest.raises(KeyFileError, match="64 hex digits"):
        load_key(bad)


def _signed_hub_test(tmp_path: Path, body: Any) -> None:
    key = new_key_file(tmp_path / "k.key")

    async def main() -> None:
        port = free_port_block(1)
        vehicle = Peer(key=key.secret)
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", f"udpin:127.0.0.1:{port}", 1, signing_key=key)
                await body(link, vehicle, port, key)
        finally:
            vehicle.close()

    _run(main())


def test_signed_link_accepts_signed_and_rejects_unsigned_wrong_key_and_replay(
        tmp_path: Path) -> None:
    async def body(link: VehicleLink, vehicle: Peer, port: int, key: Any) -> None:
        first = vehicle.heartbeat(px4.OFFBOARD, armed=True)
        vehicle.send(first, port)
        await until(lambda: link.telemetry.mode == px4.OFFBOARD, timeout=10.0, poll=0.001)
        assert link.pinned
        # everything the GCS sends is signed with the key
        link.send_setpoint(_setpoint(), 0)
        received = await vehicle.receive_until("SET_POSITION_TARGET_LOCAL_NED")
        assert all(m.get_msgbuf()[2] & mavlink.MAVLINK_IFLAG_SIGNED for m in received)
        checker = mavlink.MAVLink(None)
        checker.signing.secret_key = key.secret
        for m in received:
            assert checker.decode(bytearray(m.get_msgbuf())).get_signed()
        # from the pinned address: unsigned, signed with another key, and a replay
        unsigned = Peer()
        unsigned.sock.close()
        vehicle.send(unsigned.heartbeat(px4.POSITION), port)
        wrong = Peer(key=b"\x01" * 32)
        wrong.sock.close()
        vehicle.send(wrong.heartbeat(px4.POSITION), port)
        vehicle.send(first, port)  # replayed: same timestamp as an accepted one
        sec = link.telemetry.security
        await until(lambda: sec.total == 3, timeout=10.0, poll=0.001)
        assert (sec.unsigned, sec.bad_signature, sec.replayed) == (1, 1, 1)
        assert link.telemetry.mode == px4.OFFBOARD
        vehicle.send(vehicle.heartbeat(px4.POSITION), port)  # a fresh signed one counts
        await until(lambda: link.telemetry.mode == px4.POSITION, timeout=10.0, poll=0.001)
        assert sec.total == 3

    _signed_hub_test(tmp_path, body)


def test_a_key_not_on_the_vehicle_fails_connect_naming_the_cause(tmp_path: Path) -> None:
    """A vehicle sending unsigned packets to a link with a key is heard, not silent: the
    connect timeout says how many were dropped, from where, and why, never "no HEARTBEAT";
    one signed with another key is told apart."""
    async def body(link: VehicleLink, vehicle: Peer, port: int, key: Any) -> None:
        spec = VehicleSpec(id="uav1", connection=f"udpin:127.0.0.1:{port}", system_id=1,
                           component_id=1, home=None)
        unkeyed = Peer()
        try:
            for _ in range(3):
                unkeyed.send(unkeyed.heartbeat(), port)
                unkeyed.send(unkeyed.position(), port)
            await until(lambda: link.telemetry.security.unsigned == 6, timeout=10.0, poll=0.001)
            with pytest.raises(VehicleTimeout) as refused:
                await connect(link, spec, 0.2)
            text = str(refused.value)
            address = f"{unkeyed.address[0]}:{unkeyed.address[1]}"
            assert f"6 unsigned packets from {address}" in text
            assert "not provisioned on the vehicle" in text
            assert "(fleetplan keys provision --fleet FLEET.json)" in text  # what to do
            assert "no HEARTBEAT" not in text
        finally:
            unkeyed.close()
        other = Peer(key=b"\x02" * 32)
        try:
            other.send(other.heartbeat(), port)
            await until(lambda: link.telemetry.security.bad_signature == 1,
                        timeout=10.0, poll=0.001)
            with pytest.raises(VehicleTimeout, match=r"1 wrongly signed packets from .*another "
                                                     r"key than the fleet file's"):
                await connect(link, spec, 0.2)
        finally:
            other.close()

    _signed_hub_test(tmp_path, body)


def test_a_forged_future_timestamp_cannot_lock_the_stream_out(tmp_path: Path) -> None:
    """pymavlink's own check records a timestamp before checking the signature; ours not."""
    async def body(link: VehicleLink, vehicle: Peer, port: int, key: Any) -> None:
        forger = Peer(key=b"\x02" * 32, timestamp=signing_timestamp(time.time()) + 10**9)
        forger.sock.close()
        vehicle.send(forger.heartbeat(px4.POSITION), port)  # bad signature, huge timestamp
        vehicle.send(vehicle.heartbeat(), port)  # after it, on the same socket
        await until(lambda: link.telemetry.security.bad_signature == 1, timeout=10.0, poll=0.001)
        await until(lambda: link.telemetry.heartbeat_time is not None, timeout=10.0, poll=0.001)
        assert link.telemetry.security.total == 1

    _signed_hub_test(tmp_path, body)


def test_signing_timestamp_never_goes_backwards_across_restarts(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    key = new_key_file(tmp_path / "k.key")
    first = LinkSigning(key)
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.signing = first.state
    for _ in range(1000):
        first.pack(mav.heartbeat_encode(6, 8, 0, 0, 4), mav)
    last_used = first.state.timestamp - 1
    assert stat.S_IMODE(timestamp_path(key).stat().st_mode) == 0o600
    # the machine's clock jumps back an hour, then the GCS restarts (no clean shutdown)
    now = time.time()
    monkeypatch.setattr(signing_module.time, "time", lambda: now - 3600.0)
    second = LinkSigning(key)
    assert second.state.timestamp > last_used
    assert int(timestamp_path(key).read_text()) >= second.state.timestamp + RESERVE - 1


def test_fleet_file_names_the_key_and_the_peer_and_never_writes_the_key(
        tmp_path: Path) -> None:
    import json

    from gcs.errors import FleetFileError
    from gcs.fleet.fleetfile import FleetSpec, load_fleet

    key = new_key_file(tmp_path / "fleet.key")
    other = new_key_file(tmp_path / "uav2.key")
    fleet: dict[str, Any] = {
        "signing_key": "fleet.key",  # relative to the fleet file
        "vehicles": [
            {"id": "uav1", "connection": "udpin:127.0.0.1:14540", "system_id": 1,
             "home": [0, 0, 0], "peer": "127.0.0.1:14580"},
            {"id": "uav2", "connection": "udpin:127.0.0.1:14541", "system_id": 2,
             "home": [2, 0, 0], "signing_key": str(other.path)},
        ]}
    (tmp_path / "fleet.json").write_text(json.dumps(fleet))
    spec = load_fleet(tmp_path / "fleet.json")
    uav1, uav2 = spec.vehicles
    assert uav1.signing_key == key and uav2.signing_key == other
    assert uav1.peer == ("127.0.0.1", 14580) and uav2.peer is None
    written = json.dumps(spec.to_dict())
    assert key.secret.hex() not in written and other.secret.hex() not in written
    assert str(key.path) in written
    os.chmod(other.path, 0o644)
    with pytest.raises(FleetFileError, match=r"vehicles\[1\]\.signing_key.*group/others"):
        load_fleet(tmp_path / "fleet.json")
    bad_peer = {**fleet, "signing_key": str(key.path)}
    bad_peer["vehicles"] = [{**fleet["vehicles"][0], "peer": "nowhere"}]
    with pytest.raises(FleetFileError, match=r"vehicles\[0\]\.peer"):
        FleetSpec.from_dict(bad_peer)


def test_quick_restarts_still_accept_an_honest_vehicle(tmp_path: Path) -> None:
    """Each restart starts the GCS's own counter past the last reservation (ahead of the
    clock); a vehicle signing with the current time must still be accepted as a new stream,
    while one a minute and more behind is refused as a replay."""
    key = new_key_file(tmp_path / "k.key")
    for _ in range(10):
        signing = LinkSigning(key)
    assert signing.state.timestamp > signing_timestamp(time.time()) + RESERVE  # ahead
    vehicle = Peer(key=key.secret)
    vehicle.sock.close()
    fresh = parse_datagram(vehicle.heartbeat()).messages[0]
    assert signing.verify(fresh) is None
    old = Peer(system_id=2, key=key.secret,
               timestamp=signing_timestamp(time.time()) - 61 * 100_000)
    old.sock.close()
    assert signing.verify(parse_datagram(old.heartbeat()).messages[0]) == "replayed"


def test_two_sources_for_one_vehicle_fail_its_connect_naming_both() -> None:
    async def main() -> None:
        port = free_port_block(1)
        spoofer, vehicle = Peer(), Peer()
        spec = VehicleSpec(id="uav1", connection=f"udpin:127.0.0.1:{port}", system_id=1,
                           component_id=1, home=None)
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", spec.connection, 1)
                # the spoofer speaks first and is pinned; the real vehicle claims it too
                spoofer.send(spoofer.heartbeat(), port)
                spoofer.send(spoofer.position(), port)
                await until(lambda: link.pinned, timeout=10.0, poll=0.001)
                vehicle.send(vehicle.heartbeat(), port)
                await until(lambda: link.claimants, timeout=10.0, poll=0.001)
                with pytest.raises(LinkError) as refused:
                    await connect(link, spec, 5.0)
                text = str(refused.value)
                for address in (spoofer.address, vehicle.address):
                    assert f"{address[0]}:{address[1]}" in text
                assert "peer" in text  # what to do about it
        finally:
            vehicle.close()
            spoofer.close()

    _run(main())


def test_a_vehicle_pinned_up_front_connects_beside_a_spoofer() -> None:
    async def main() -> None:
        port = free_port_block(1)
        spoofer, vehicle = Peer(), Peer()
        spec = VehicleSpec(id="uav1", connection=f"udpin:127.0.0.1:{port}", system_id=1,
                           component_id=1, home=None, peer=vehicle.address)
        try:
            async with LinkHub() as hub:
                link = await hub.add("uav1", spec.connection, 1, peer=vehicle.address)
                spoofer.send(spoofer.heartbeat(), port)
                vehicle.send(vehicle.heartbeat(), port)
                vehicle.send(vehicle.position(), port)
                await connect(link, spec, 5.0)  # the spoofer is known foreign: no dispute
                assert link.claimants == [] and link.telemetry.security.foreign_source == 1
        finally:
            vehicle.close()
            spoofer.close()

    _run(main())


def test_the_mocks_fleet_file_pins_each_mock_by_its_address() -> None:
    mock = MockFleet(homes=[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], **mock_ports(2))
    fleet = FleetSpec.from_dict(mock.fleet_dict())
    assert [v.peer for v in fleet.vehicles] == [v.listen_address for v in mock.vehicles]
