"""gcs.sim (the mock) behaves like PX4 for what we use: protocol, mode rules, failsafes, and a real
MAVLink client (MAVSDK) can fly it."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

from gcs.autopilot import px4
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.setpoints import Setpoint, hold_track
from gcs.sim import MockFleet
from gcs.wire import mavlink
from tests.flight.flying import stream_setpoint
from tests.flight.support import FAST_MOCK, mock_ports
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(90)


async def _connect(mock: MockFleet, hub: LinkHub, index: int = 0) -> VehicleLink:
    link = await hub.add(f"v{index}", mock.gcs_url(index), index + 1)
    assert await link.wait_for(lambda t: t.heartbeat_time is not None
                               and t.position_ned is not None, 5.0)
    return link


def test_px4_identity_and_requests() -> None:
    async def main() -> None:
        async with MockFleet(2, settle_time=0.5, **mock_ports(2)) as mock, \
                LinkHub() as hub:
            link = await _connect(mock, hub, 1)
            tel = link.telemetry
            assert tel.autopilot == mavlink.MAV_AUTOPILOT_PX4
            assert tel.vehicle_type == mavlink.MAV_TYPE_QUADROTOR
            assert tel.mode == px4.HOLD and not tel.armed
            got: list[str] = []
            link.listeners.append(lambda _l, msg, _t: got.append(msg.get_type()))
            for msg_id in (mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                           mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN,
                           mavlink.MAVLINK_MSG_ID_HOME_POSITION):
                assert await link.request_message(msg_id) == mavlink.MAV_RESULT_ACCEPTED
            assert await link.request_message(mavlink.MAVLINK_MSG_ID_WIND_COV) == \
                mavlink.MAV_RESULT_UNSUPPORTED
            await asyncio.sleep(1.2)  # the 1 Hz streams come round once
            assert {"AUTOPILOT_VERSION", "GPS_GLOBAL_ORIGIN", "HOME_POSITION", "HEARTBEAT",
                    "SYS_STATUS", "EXTENDED_SYS_STATE", "ATTITUDE",
                    "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"} <= set(got)
            # vehicle 1's origin is 2 m east of vehicle 0's: GPS_GLOBAL_ORIGIN says so
            assert tel.gps_origin is not None
            assert tel.gps_origin[1] > mock.vehicles[0].origin.lon
            # REQUEST_MESSAGE is ACKed twice, like PX4: the duplicate is tolerated
            assert link.duplicate_acks >= 3

    asyncio.run(main())


def test_offboard_and_arming_rules() -> None:
    async def main() -> None:
        async with MockFleet(1, settle_time=1.5, **mock_ports(1)) as mock, LinkHub() as hub:
            link = await _connect(mock, hub)
            offboard = px4.OFFBOARD.command_params
            # no setpoint yet: OFFBOARD refused
            assert await link.command(mavlink.MAV_CMD_DO_SET_MODE, offboard) == \
                mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            # estimator still settling: arming refused for now
            assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == \
                mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            await asyncio.sleep(0.1)  # the STATUSTEXT after the ACK
            assert list(link.telemetry.statustexts)[-3:] == [
                "Preflight Fail: heading estimate not stable",
                "Arming denied: Resolve system health failures ",  # MAVLink 2 chunks
                "first"]
            # setpoints PX4 would ignore do not count as a live stream
            vehicle = mock.vehicles[0]
            bad = [
                dict(coordinate_frame=6),                      # MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
                dict(type_mask=0x0FFF),                         # everything ignored
                dict(type_mask=0x0A00),                         # FORCE with acceleration
                dict(target_system=7),                          # someone else's
            ]
            base = Setpoint((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)
            for change in bad:
                fields = base.fields(1, 1, 0) | change
                link.send(link.endpoint.mav.set_position_target_local_ned_encode(**fields))
            await asyncio.sleep(0.2)
            assert vehicle.setpoints_accepted == 0
            assert vehicle.setpoints_ignored == 3  # the misaddressed one is not even looked at
            assert await link.command(mavlink.MAV_CMD_DO_SET_MODE, offboard) == \
                mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            # one recent valid setpoint is enough (PX4 offboardCheck: within COM_OF_LOSS_T)
            link.send_setpoint(base, 0)
            await asyncio.sleep(0.1)
            assert await link.command(mavlink.MAV_CMD_DO_SET_MODE, offboard) == \
                mavlink.MAV_RESULT_ACCEPTED
            # stream at once: the 1 Hz HEARTBEAT confirming OFFBOARD may take longer than
            # COM_OF_LOSS_T on a busy machine
            stream = asyncio.create_task(stream_setpoint(link, base))
            try:
                assert await link.wait_for(lambda t: t.mode == px4.OFFBOARD, 2.0)
                await asyncio.sleep(0.2)
                assert link.duplicate_acks >= 1  # DO_SET_MODE answered twice
                await until(lambda: mock.now() >= 1.5, "the mock's clock at 1.5 s",
                            timeout=60.0, poll=0.1)
                assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == \
                    mavlink.MAV_RESULT_ACCEPTED
                assert await link.wait_for(lambda t: t.armed, 2.0)
                # The model climbs to the 1 m setpoint in about 2.5 s; a loaded machine
                # may take longer in wall time, so wait for it with a deadline.
                await until(lambda: abs(vehicle.position_ned[2] + 1.0) <= 0.05,
                            "the climb to the 1 m setpoint", timeout=30.0, poll=0.1,
                            detail=lambda: f"mode {link.telemetry.mode}, armed "
                            f"{link.telemetry.armed}, texts "
                            f"{list(link.telemetry.statustexts)[-3:]}")
                assert vehicle.position_ned[2] == pytest.approx(-1.0, abs=0.05), (
                    f"mode {link.telemetry.mode}, armed {link.telemetry.armed}, "
                    f"texts {list(link.telemetry.statustexts)[-3:]}"
                )
                # disarming in the air is refused unless forced
                assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (0.0,)) == \
                    mavlink.MAV_RESULT_DENIED
            finally:
                stream.cancel()

    asyncio.run(main())


def test_setpoints_stop_trigger_the_failsafe_then_land_and_disarm() -> None:
    async def main() -> None:
        # HEARTBEAT at 20 Hz (configured, as PX4 refuses to change it over MAVLink) so that
        # the short Position phase shows in it
        # (and the quick landing of QUICK_MOCK: the failsafe's landing is what is checked)
        async with MockFleet(1, settle_time=0.2, failsafe_action_delay=0.5,
                             **{**FAST_MOCK, "status_rate": 20.0},
                             **mock_ports(1)) as mock, LinkHub() as hub:
            link = await _connect(mock, hub)
            vehicle = mock.vehicles[0]
            stream = asyncio.create_task(
                stream_setpoint(link, hold_track([0, 0, -1.5], 0.0, 20).at(0)))
            assert await link.wait_for(lambda _t: vehicle.setpoints_accepted > 0
                                       and mock.now() >= mock.config.settle_time, 2.0)
            assert await link.command(mavlink.MAV_CMD_DO_SET_MODE,
                                      px4.OFFBOARD.command_params) == 0
            assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == 0
            assert await link.wait_for(lambda _t: vehicle.in_air, 5.0)
            assert vehicle.mode == px4.OFFBOARD
            stream.cancel()
            assert await link.wait_for(lambda t: t.mode == px4.POSITION, 3.0)
            # COM_OF_LOSS_T after the last setpoint, on the vehicle's own clock: never
            # earlier, and within its rule tick (a loose bound for a busy machine)
            failsafe = next(t for t, e in vehicle.events if e == "failsafe: offboard loss")
            waited = failsafe - vehicle.last_setpoint_time
            assert waited > mock.config.offboard_loss_timeout
            assert waited < mock.config.offboard_loss_timeout + 0.5  # bound
            assert any("offboard" in text for text in link.telemetry.statustexts)
            assert await link.wait_for(lambda t: t.mode == px4.LAND, 3.0)
            assert await link.wait_for(lambda t: not t.armed, 10.0)
            assert vehicle.position_ned[2] == pytest.approx(0.0, abs=1e-6)
            assert [e for _, e in vehicle.events if "failsafe" in e]

    asyncio.run(main())


def test_auto_disarm_when_armed_without_taking_off() -> None:
    async def main() -> None:
        async with MockFleet(1, settle_time=0.0, disarm_preflight=1.5, status_rate=20.0,
                             **mock_ports(1)) as mock, LinkHub() as hub:
            link = await _connect(mock, hub)
            # like PX4: HEARTBEAT's rate cannot be changed, LOCAL_POSITION_NED's can
            assert await link.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                                      (0.0, 50_000.0)) == mavlink.MAV_RESULT_FAILED
            assert await link.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                                      (32.0, 20_000.0)) == mavlink.MAV_RESULT_ACCEPTED
            assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == 0
            assert await link.wait_for(lambda t: t.armed, 2.0)
            assert await link.wait_for(lambda t: not t.armed, 3.0)
            assert not mock.vehicles[0].in_air
            assert any("preflight" in e for _, e in mock.vehicles[0].events)

    asyncio.run(main())


@pytest.mark.flight
def test_mavsdk_flies_the_mock() -> None:
    """MAVSDK's native 4.x API connects, sees a PX4 autopilot, arms (after the settling time),
    starts offboard with position setpoints, and the mock's reported position gets there."""
    from mavsdk.asyncio import Autopilot, ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.offboard import OffboardAsync, PositionNedYaw
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    async def main() -> None:
        ports = mock_ports(1)
        async with MockFleet(1, settle_time=0.5, **ports) as mock:
            config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
            async with Mavsdk(config) as sdk:
                await sdk.add_any_connection(f"udpin://127.0.0.1:{ports['gcs_base_port']}")
                system = await sdk.first_autopilot(timeout_s=10.0)
                assert system is not None
                assert await system.autopilot_type() == Autopilot.PX4
                assert await system.get_system_id() == 1
                action, offboard = ActionAsync(system), OffboardAsync(system)
                telemetry = TelemetryAsync(system)

                async def armed() -> bool:
                    try:
                        await action.arm()
                    except Exception:  # TEMPORARILY_REJECTED while settling: an error
                        return False
                    return True

                await until(armed, "MAVSDK's arm to be accepted", timeout=30.0, poll=0.2)
                assert mock.vehicles[0].armed
                await offboard.set_position_ned(PositionNedYaw(0.5, -1.0, -1.5, 90.0))
                await offboard.start()
                target = np.array([0.5, -1.0, -1.5])
                reported: list[np.ndarray] = []

                async def at_target() -> bool:  # MAVSDK's latest LOCAL_POSITION_NED
                    p = (await telemetry.position_velocity_ned()).position
                    reported.append(np.array([p.north_m, p.east_m, p.down_m]))
                    return bool(np.linalg.norm(reported[-1] - target) < 0.05)

                await until(at_target, "MAVSDK's position at the target", timeout=30.0,
                            detail=lambda: reported[-1])
                np.testing.assert_allclose(reported[-1], target, atol=0.05)
                assert mock.vehicles[0].mode == px4.OFFBOARD
                assert mock.vehicles[0].setpoints_accepted > 20

    asyncio.run(main())


def test_a_cancelled_command_does_not_block_the_next() -> None:
    """An abort cancels the flow while it waits for an ACK; the disarm that follows with the
    same command id must still go out."""
    async def main() -> None:
        async with MockFleet(1, settle_time=30.0, **mock_ports(1)) as mock, \
                LinkHub() as hub:
            link = await _connect(mock, hub)
            mock.vehicles[0].faults.loss = 1.0  # the ACK of the first try never comes
            waiting = asyncio.create_task(
                link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,), timeout=5.0))
            await asyncio.sleep(0.2)
            waiting.cancel()
            with pytest.raises(asyncio.CancelledError):
                await waiting
            mock.vehicles[0].faults.loss = 0.0
            # arming is TEMPORARILY_REJECTED (settling); what matters is that it is answered
            result = await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (0.0,))
            assert result == mavlink.MAV_RESULT_ACCEPTED

    asyncio.run(main())


def test_signing_provisioned_with_setup_signing_like_px4(tmp_path) -> None:
    """PX4's signing rules: SETUP_SIGNING unsigned only while there is no key; then signed
    output, unsigned input rejected except HEARTBEAT & co.; a wrong key is rejected."""
    from gcs.errors import CommandError
    from gcs.wire import load_key, new_key_file, signing_timestamp

    key = new_key_file(tmp_path / "fleet.key")
    other = new_key_file(tmp_path / "other.key")
    request = mavlink.MAV_CMD_REQUEST_MESSAGE
    version = (float(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION),)

    async def main() -> None:
        async with MockFleet(1, settle_time=0.0, **mock_ports(1)) as mock:
            vehicle = mock.vehicles[0]
            async with LinkHub() as hub:  # the trusted provisioning link
                link = await _connect(mock, hub)
                link.send_setup_signing(key, signing_timestamp(time.time()))
                await asyncio.sleep(0.2)
                assert vehicle.signing_key == key.secret
                # unsigned commands are now rejected (no ACK); HEARTBEAT still accepted
                before = vehicle.signing.unsigned_count
                with pytest.raises(CommandError):
                    await link.command(request, version, timeout=0.2, retries=1)
                assert vehicle.signing.reject_count >= 2
                await asyncio.sleep(1.1)  # the GCS heartbeat comes round
                assert vehicle.signing.unsigned_count > before
                # an unsigned SETUP_SIGNING cannot change the key any more
                link.send_setup_signing(other, signing_timestamp(time.time()))
                await asyncio.sleep(0.1)
                assert vehicle.signing_key == key.secret
            async with LinkHub() as hub:  # signed with the wrong key: refused both ways
                link = await hub.add("v0", mock.gcs_url(0), 1, signing_key=load_key(other.path),
                                     peer=vehicle.listen_address)
                with pytest.raises(CommandError):
                    await link.command(request, version, timeout=0.2, retries=1)
                assert link.telemetry.heartbeat_time is None
                assert link.telemetry.security.bad_signature > 0
                assert vehicle.signing.badsig_count >= 2
            async with LinkHub() as hub:  # signed with the key: everything works
                link = await hub.add("v0", mock.gcs_url(0), 1, signing_key=key)
                assert await link.wait_for(lambda t: t.heartbeat_time is not None, 3.0)
                assert await link.command(request, version) == mavlink.MAV_RESULT_ACCEPTED
                assert link.telemetry.security.total == 0
                # the vehicle's messages carry a signature with the key
                assert vehicle.signing.goodsig_count > 0

    asyncio.run(main())


def test_absurd_setpoints_are_refused_and_the_fleet_keeps_serving() -> None:
    """NaN, inf and absurd magnitudes in a used setpoint field are refused and counted; the
    vehicle keeps its last valid setpoint; it and the others keep talking and flying."""
    inf, nan = float("inf"), float("nan")

    async def main() -> None:
        async with MockFleet(2, settle_time=0.2, **mock_ports(2)) as mock, LinkHub() as hub:
            link = await _connect(mock, hub, 0)
            other = await _connect(mock, hub, 1)
            vehicle = mock.vehicles[0]
            valid = Setpoint((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)
            stream = asyncio.create_task(stream_setpoint(link, valid))
            try:
                await asyncio.sleep(0.2)
                assert await link.command(mavlink.MAV_CMD_DO_SET_MODE,
                                          px4.OFFBOARD.command_params) == \
                    mavlink.MAV_RESULT_ACCEPTED
                await asyncio.sleep(0.2)
                assert mock.model.position_sp[0].tolist() == [0.0, 0.0, -1.0]
                bad = [dict(x=nan), dict(z=inf), dict(y=-inf), dict(x=1e30), dict(z=-3e38),
                       dict(vx=1e30), dict(vz=nan), dict(afy=inf), dict(afz=-1e20),
                       dict(yaw=nan)]
                accepted = vehicle.setpoints_accepted
                for change in bad:
                    fields = valid.fields(1, 1, 0) | change
                    link.send(link.endpoint.mav.set_position_target_local_ned_encode(**fields))
                # an ignored field may hold anything: not refused
                fields = valid.fields(1, 1, 0) | dict(
                    x=nan, y=nan, z=nan,
                    type_mask=valid.fields(1, 1, 0)["type_mask"] | 0b111)
                link.send(link.endpoint.mav.set_position_target_local_ned_encode(**fields))
                await asyncio.sleep(0.3)
                assert vehicle.setpoints_invalid == len(bad)
                assert vehicle.setpoints_accepted > accepted  # the stream goes on
                assert vehicle.errors == 0 and mock.errors == 0
                # still holding the last valid setpoint, state finite, still OFFBOARD
                assert mock.model.position_sp[0].tolist() == [0.0, 0.0, -1.0]
                assert np.all(np.isfinite(vehicle.position_ned))
                assert vehicle.mode == px4.OFFBOARD
                # both vehicles keep sending telemetry
                seen = {0: 0, 1: 0}
                link.listeners.append(lambda _l, m, _t: seen.__setitem__(0, seen[0] + 1))
                other.listeners.append(lambda _l, m, _t: seen.__setitem__(1, seen[1] + 1))
                await asyncio.sleep(0.5)
                assert seen[0] > 5 and seen[1] > 5, seen
                # a new valid setpoint is taken
                stream.cancel()
                link.send_setpoint(Setpoint((1.0, 0.0, -2.0), (0.0, 0.0, 0.0),
                                            (0.0, 0.0, 0.0), 0.0), 0)
                await asyncio.sleep(0.2)
                assert mock.model.position_sp[0].tolist() == [1.0, 0.0, -2.0]
            finally:
                stream.cancel()

    asyncio.run(main())


def test_a_failing_vehicle_does_not_silence_the_fleet() -> None:
    """A vehicle whose state is garbage (1e308: its telemetry encoders raise OverflowError) is
    counted and recovered; the fleet loop and the other vehicles go on."""
    async def main() -> None:
        async with MockFleet(2, settle_time=0.2, **mock_ports(2)) as mock, LinkHub() as hub:
            other = await _connect(mock, hub, 1)
            mock.model.position[0] = (1e308, 0.0, -1.0)
            mock.model.velocity[0] = (1e308, 0.0, 0.0)
            mock.vehicles[0].faults.battery = float("inf")  # SYS_STATUS encoding raises
            seen: list[str] = []
            other.listeners.append(lambda _l, m, _t: seen.append(m.get_type()))
            await asyncio.sleep(1.5)
            assert mock.vehicles[0].errors >= 1  # caught in the fleet loop, counted
            assert mock.vehicles[1].errors == 0
            assert {"LOCAL_POSITION_NED", "SYS_STATUS", "HEARTBEAT"} <= set(seen)
            assert mock.model.recovered >= 1
            assert np.all(np.isfinite(mock.model.position))
            assert np.all(np.abs(mock.vehicles[0].position_ned) <= 1e6)
            link = await _connect(mock, hub, 0)  # vehicle 0 itself talks again
            assert link.telemetry.position_ned is not None

    asyncio.run(main())


def test_statustexts_are_never_cut() -> None:
    """Every STATUSTEXT of a flight fits 50 bytes or goes as MAVLink 2 chunks cut after a
    space; the same text is not repeated on retries."""
    from gcs.sim.statustext import statustext_chunks

    for text in ("Arming denied: Resolve system health failures first", "x" * 120,
                 "short", "a " * 25 + "end", "Failsafe activated: offboard signal lost"):
        chunks = statustext_chunks(text)
        assert "".join(chunks) == text
        assert all(len(c.encode()) <= 50 for c in chunks)
        if len(chunks) > 1:
            assert len(chunks[-1].encode()) < 50  # NUL padding marks the last chunk
            assert all(c.endswith(" ") for c in chunks[:-1]) or " " not in text

    async def main() -> None:
        # landing and auto-disarm shortened (FAST_MOCK): the texts are what is checked
        async with MockFleet(1, settle_time=1.0, **mock_ports(1), **FAST_MOCK) as mock, \
                LinkHub() as hub:
            link = await _connect(mock, hub)
            raw: list[tuple[str, int, int]] = []
            link.listeners.append(lambda _l, m, _t: raw.append(
                (m.text, m.id, m.chunk_seq)) if m.get_type() == "STATUSTEXT" else None)
            for _ in range(4):  # a GCS retrying arming while the vehicle settles
                assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == \
                    mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            await asyncio.sleep(0.1)
            texts = [t for t, _i, _s in raw]
            assert texts.count("Preflight Fail: heading estimate not stable") == 1
            assert texts.count("first") == 1
            # a normal flight: offboard, arm, climb, land, auto-disarm
            sp = Setpoint((0.0, 0.0, -0.5), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)
            stream = asyncio.create_task(stream_setpoint(link, sp))
            try:
                await until(lambda: mock.now() >= 1.1, "the mock's clock at 1.1 s",
                            timeout=60.0, poll=0.1)
                assert await link.command(mavlink.MAV_CMD_DO_SET_MODE,
                                          px4.OFFBOARD.command_params) == \
                    mavlink.MAV_RESULT_ACCEPTED
                assert await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)) == \
                    mavlink.MAV_RESULT_ACCEPTED
                await asyncio.sleep(1.0)
            finally:
                stream.cancel()
            assert await link.command(mavlink.MAV_CMD_NAV_LAND, ()) == \
                mavlink.MAV_RESULT_ACCEPTED
            assert await link.wait_for(lambda t: not t.armed, 15.0)
            await asyncio.sleep(0.2)
            assert any(t.startswith("Disarmed by") for t in texts + [r[0] for r in raw])
            for text, text_id, seq in raw:
                assert len(text.encode()) <= 50
                if len(text.encode()) == 50 or seq > 0:
                    assert text_id != 0  # part of a chunked text
            # reassembled, every text is whole and the vehicle's record says the same
            whole: dict[int, str] = {}
            plain = []
            for text, text_id, _seq in raw:
                if text_id == 0:
                    plain.append(text)
                else:
                    whole[text_id] = whole.get(text_id, "") + text
            assert sorted(plain + list(whole.values())) == sorted(mock.vehicles[0].statustexts)

    asyncio.run(main())
