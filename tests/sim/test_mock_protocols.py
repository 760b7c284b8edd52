"""The mock speaks what ground stations need, as PX4 does: parameters, missions, fences and
rally points, TIMESYNC, PROTOCOL_VERSION, AUTO.TAKEOFF, AUTO.RTL, POSCTL refusal, explanations
of refused setpoints, honest capabilities, the geofence bit, links that latch their first
partner, and the optional GCS link. Checked with a bare pymavlink client (`mavclient`)."""

from __future__ import annotations

import asyncio
import contextlib
import math
import socket
import struct
import time
from collections.abc import AsyncIterator
from typing import Any

import numpy as np
import pytest

from gcs.autopilot import px4
from gcs.sim import DEFAULT_WORLD_ORIGIN, MockFleet
from gcs.sim.paramdefs import PX4_PARAMS
from gcs.sim.params import encode_value
from gcs.wire import mavlink
from tests.flight.support import mock_ports
from tests.sim.mavclient import MavClient
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(60)

_m = mavlink
_FENCE = _m.MAV_MISSION_TYPE_FENCE
_RALLY = _m.MAV_MISSION_TYPE_RALLY


@contextlib.asynccontextmanager
async def _vehicle(count: int = 1, index: int = 0, **overrides: Any
                   ) -> AsyncIterator[tuple[MockFleet, MavClient]]:
    """A mock fleet and a pymavlink client on vehicle `index`'s offboard link."""
    settings: dict[str, Any] = {"settle_time": 0.0, **overrides}
    async with MockFleet(count, **mock_ports(count), **settings) as mock:
        v = mock.vehicles[index]
        async with MavClient(v.gcs_address, v.listen_address, v.system_id) as client:
            client.heartbeat()
            await client.wait("HEARTBEAT", timeout=3.0, since=0.0)
            yield mock, client


def _param_value(msg: Any) -> float:
    """A PARAM_VALUE's value, decoded as PX4 encodes it (INT32 byte-wise)."""
    if msg.param_type == _m.MAV_PARAM_TYPE_INT32:
        return float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])
    return float(msg.param_value)


# ------------------------------------------------------------------------ parameters


def test_parameter_list_read_and_set_as_px4() -> None:
    async def main() -> None:
        async with _vehicle(2, index=1) as (mock, c):
            c.send(c.mav.param_request_list_encode(2, 1))
            total = len(PX4_PARAMS)
            await until(lambda: len({m.param_index for m in c.messages("PARAM_VALUE")})
                        >= total + 1, "the whole parameter list", timeout=30.0)
            values = c.messages("PARAM_VALUE")
            assert values[0].param_id == "_HASH_CHECK" and values[0].param_index == 65535
            listed = {m.param_id: m for m in values[1:]}
            assert len(listed) == total >= 100
            assert {m.param_count for m in values} == {total}
            assert sorted(m.param_index for m in listed.values()) == list(range(total))
            for name in ("COM_OF_LOSS_T", "COM_DISARM_LAND", "COM_DISARM_PRFLT",
                         "MPC_XY_VEL_MAX", "MPC_Z_VEL_MAX_UP", "MPC_LAND_SPEED", "GF_ACTION",
                         "GF_MAX_HOR_DIST", "GF_MAX_VER_DIST", "MAV_SYS_ID", "NAV_RCL_ACT",
                         "COM_RCL_EXCEPT", "MIS_TAKEOFF_ALT", "RTL_RETURN_ALT",
                         "SYS_AUTOSTART"):
                assert name in listed, name
            # PX4's types, INT32 byte-wise: vehicle 2 says MAV_SYS_ID 2
            assert listed["MAV_SYS_ID"].param_type == _m.MAV_PARAM_TYPE_INT32
            assert _param_value(listed["MAV_SYS_ID"]) == 2.0
            assert _param_value(listed["SYS_AUTOSTART"]) == 10040.0
            assert listed["COM_OF_LOSS_T"].param_type == _m.MAV_PARAM_TYPE_REAL32
            assert _param_value(listed["COM_OF_LOSS_T"]) == pytest.approx(1.0)

            # read by name and by index
            since = time.monotonic()
            c.send(c.mav.param_request_read_encode(2, 1, b"GF_ACTION", -1))
            got = await c.wait("PARAM_VALUE", lambda m: m.param_id == "GF_ACTION", since=since)
            assert _param_value(got) == 2.0
            index = listed["MPC_XY_VEL_MAX"].param_index
            c.send(c.mav.param_request_read_encode(2, 1, b"", index))
            got = await c.wait("PARAM_VALUE", lambda m: m.param_index == index, since=since)
            assert got.param_id == "MPC_XY_VEL_MAX" and _param_value(got) == 12.0
            c.send(c.mav.param_request_read_encode(2, 1, b"NO_SUCH_PARAM", -1))
            await c.wait("STATUSTEXT", lambda m: m.text == "[pm] unknown param: NO_SUCH_PARAM",
                         since=since)

            # set: answered with the new value, and the vehicle's behaviour follows
            since = time.monotonic()
            c.set_param("COM_OF_LOSS_T", 3.5)
            got = await c.wait("PARAM_VALUE", lambda m: m.param_id == "COM_OF_LOSS_T",
                               since=since)
            assert _param_value(got) == pytest.approx(3.5)
            assert mock.vehicles[1].config.offboard_loss_timeout == pytest.approx(3.5)
            assert mock.vehicles[0].config.offboard_loss_timeout == pytest.approx(1.0)
            c.set_param("MPC_XY_VEL_MAX", 4.0)
            await c.wait("PARAM_VALUE", lambda m: m.param_id == "MPC_XY_VEL_MAX", since=since)
            assert list(mock.model.velocity_xy_max) == [12.0, 4.0]  # this vehicle's limit
            c.set_param("GF_ACTION", 1, _m.MAV_PARAM_TYPE_INT32,
                        field=encode_value("i", 1))
            got = await c.wait("PARAM_VALUE", lambda m: m.param_id == "GF_ACTION", since=since)
            assert _param_value(got) == 1.0 and mock.vehicles[1].config.geofence_action == 1

            # refused as PX4 refuses: unknown name, wrong type (no PARAM_VALUE); out of range
            # (the mock: PARAM_VALUE with the unchanged value)
            since = time.monotonic()
            c.set_param("NO_SUCH_PARAM", 1.0)
            c.set_param("MAV_SYS_ID", 7.0)  # REAL32 for an INT32 parameter
            c.set_param("MPC_LAND_SPEED", -1.0)
            got = await c.wait("PARAM_VALUE", lambda m: m.param_id == "MPC_LAND_SPEED",
                               since=since)
            assert _param_value(got) == pytest.approx(0.7)
            assert mock.vehicles[1].config.land_speed == pytest.approx(0.7)
            await c.wait("STATUSTEXT", lambda m: m.text.startswith("[pm] MPC_LAND_SPEED"),
                         since=since)
            await asyncio.sleep(0.3)
            texts = c.texts()
            assert "[pm] unknown param: NO_SUCH_PARAM" in texts
            assert "[pm] param types mismatch param: MAV_SYS_ID" in texts
            assert not [m for m in c.messages("PARAM_VALUE", since)
                        if m.param_id in ("NO_SUCH_PARAM", "MAV_SYS_ID")]

    asyncio.run(main())


def test_a_parameter_changes_the_vehicle_behaviour() -> None:
    """COM_DISARM_PRFLT set to 1 s: armed on the ground, it disarms after about 1 s, not 10."""
    async def main() -> None:
        async with _vehicle() as (mock, c):
            c.set_param("COM_DISARM_PRFLT", 1.0)
            await c.wait("PARAM_VALUE", lambda m: m.param_id == "COM_DISARM_PRFLT", since=0.0)
            c.command(_m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            assert await c.ack(_m.MAV_CMD_COMPONENT_ARM_DISARM, since=0.0) == \
                _m.MAV_RESULT_ACCEPTED
            # the bound tells the 1 s set from the default 10 s
            await until(lambda: not mock.vehicles[0].armed, "the preflight disarm after 1 s",
                        timeout=6.0)
            assert "Disarmed by auto preflight disarming" in c.texts()

    asyncio.run(main())


# --------------------------------------------------------------------------- missions


async def _download(c: MavClient, mission_type: int) -> list[Any]:
    since = time.monotonic()
    c.send(c.mav.mission_request_list_encode(1, 1, mission_type))
    count = (await c.wait("MISSION_COUNT", lambda m: m.mission_type == mission_type,
                          since=since)).count
    items = []
    for seq in range(count):
        c.send(c.mav.mission_request_int_encode(1, 1, seq, mission_type))
        items.append(await c.wait("MISSION_ITEM_INT", lambda m, s=seq: m.seq == s,
                                  since=since))
    c.send(c.mav.mission_ack_encode(1, 1, _m.MAV_MISSION_ACCEPTED, mission_type))
    return items


async def _upload(c: MavClient, mission_type: int, items: list[tuple[int, float, float, float]]
                  ) -> int:
    """Upload (command, param1, lat, lon) items; the vehicle's MISSION_ACK result."""
    since = time.monotonic()
    c.send(c.mav.mission_count_encode(1, 1, len(items), mission_type))
    answered: set[int] = set()

    def acks() -> list[Any]:
        """The vehicle's MISSION_ACKs so far; until one comes, each new request answered."""
        got_acks = [m for m in c.messages("MISSION_ACK", since)
                    if m.mission_type == mission_type]
        for got in [] if got_acks else c.messages("MISSION_REQUEST_INT", since):
            if got.seq in answered:
                continue
            command, p1, lat, lon = items[got.seq]
            c.send(c.mav.mission_item_int_encode(
                1, 1, got.seq, _m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, command, 0, 1, p1, 0, 0,
                math.nan, round(lat * 1e7), round(lon * 1e7), 5.0, mission_type))
            answered.add(got.seq)
        return got_acks

    return int((await until(acks, "a MISSION_ACK", timeout=15.0, poll=0.01))[0].type)


def test_mission_fence_and_rally_upload_download_clear() -> None:
    async def main() -> None:
        async with _vehicle() as (mock, c):
            for mission_type in (_m.MAV_MISSION_TYPE_MISSION, _FENCE, _RALLY):
                assert await _download(c, mission_type) == []  # MISSION_COUNT 0 when empty
            lat, lon = 47.3977, 8.5456
            square = [(_m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4.0, lat + dy, lon + dx)
                      for dy, dx in ((0, 0), (1e-4, 0), (1e-4, 1e-4), (0, 1e-4))]
            hole = [(_m.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 3.0, lat + 5e-5, lon + 5e-5)]
            assert await _upload(c, _FENCE, square + hole) == _m.MAV_MISSION_ACCEPTED
            fence = await _download(c, _FENCE)
            assert [m.command for m in fence] == [5001] * 4 + [5004]
            assert fence[2].x == round((lat + 1e-4) * 1e7) and fence[4].param1 == 3.0
            shapes = mock.vehicles[0].missions.fence
            assert [(s.inclusion, len(s.vertices), s.radius) for s in shapes] == \
                [(True, 4, None), (False, 1, 3.0)]
            rally = [(_m.MAV_CMD_NAV_RALLY_POINT, 0.0, lat, lon)]
            assert await _upload(c, _RALLY, rally) == _m.MAV_MISSION_ACCEPTED
            waypoints = [(_m.MAV_CMD_NAV_WAYPOINT, 0.0, lat, lon),
                         (_m.MAV_CMD_NAV_WAYPOINT, 0.0, lat + 1e-4, lon)]
            assert await _upload(c, _m.MAV_MISSION_TYPE_MISSION, waypoints) == \
                _m.MAV_MISSION_ACCEPTED
            assert len(await _download(c, _RALLY)) == 1
            assert [m.seq for m in await _download(c, _m.MAV_MISSION_TYPE_MISSION)] == [0, 1]
            # a waypoint is no fence item; a polygon needs three vertices: refused
            assert await _upload(c, _FENCE, waypoints) == _m.MAV_MISSION_UNSUPPORTED
            bad = [(_m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 2.0, lat, lon)] * 2
            assert await _upload(c, _FENCE, bad) == _m.MAV_MISSION_INVALID_PARAM1
            assert len(await _download(c, _FENCE)) == 5  # the refused uploads changed nothing
            # clear one list, then all of them
            since = time.monotonic()
            c.send(c.mav.mission_clear_all_encode(1, 1, _FENCE))
            await c.wait("MISSION_ACK", lambda m: m.mission_type == _FENCE, since=since)
            assert await _download(c, _FENCE) == []
            assert len(await _download(c, _RALLY)) == 1
            c.send(c.mav.mission_clear_all_encode(1, 1, _m.MAV_MISSION_TYPE_ALL))
            await c.wait("MISSION_ACK", lambda m: m.mission_type == _m.MAV_MISSION_TYPE_ALL,
                         since=since)
            for mission_type in (_m.MAV_MISSION_TYPE_MISSION, _FENCE, _RALLY):
                assert await _download(c, mission_type) == []

    asyncio.run(main())


def test_mission_upload_is_re_requested_then_given_up() -> None:
    """An unanswered MISSION_REQUEST_INT is sent again (PX4: every 0.25 s), and the transfer is
    given up with PX4's "Operation timeout" after 5 s without progress."""
    async def main() -> None:
        async with _vehicle() as (_mock, c):
            since = time.monotonic()
            c.send(c.mav.mission_count_encode(1, 1, 3, _FENCE))
            await asyncio.sleep(1.2)
            requests = c.messages("MISSION_REQUEST_INT", since)
            assert len(requests) >= 3 and {m.seq for m in requests} == {0}
            await c.wait("STATUSTEXT", lambda m: m.text == "Operation timeout", timeout=8.0,
                         since=since)
            assert await _download(c, _FENCE) == []  # nothing stored

    asyncio.run(main())


# ----------------------------------------------------------------- other requests


def test_timesync_and_protocol_version() -> None:
    async def main() -> None:
        async with _vehicle() as (_mock, c):
            since = time.monotonic()
            c.send(c.mav.timesync_encode(0, 123456789))
            got = await c.wait("TIMESYNC", lambda m: m.ts1 == 123456789, since=since)
            assert got.tc1 > 0  # the vehicle's clock, ns since boot

            for ask in (lambda: c.command(_m.MAV_CMD_REQUEST_PROTOCOL_VERSION, 1.0),
                        lambda: c.command(_m.MAV_CMD_REQUEST_MESSAGE, 300.0)):
                c.raw.clear()
                ask()
                await c.wait("COMMAND_ACK", since=time.monotonic() - 0.01)
                found = await until(lambda: next((d for d in c.raw if d[0] == 0xFD
                                                  and int.from_bytes(d[7:10], "little") == 300),
                                                 None), "a PROTOCOL_VERSION", timeout=10.0,
                                    poll=0.02)
                payload = found[10:10 + found[1]] + bytes(22)
                assert struct.unpack_from("<HHH", payload) == (200, 100, 200)

    asyncio.run(main())


def test_mavftp_has_no_files() -> None:
    """Every MAVFTP file request is answered NAK FileNotFound (a ground station falls back at
    once); a session reset is ACKed."""
    async def main() -> None:
        async with _vehicle() as (_mock, c):
            for seq, opcode, reply, error in ((7, 4, 129, 10), (9, 3, 129, 10), (11, 2, 128, None)):
                request = seq.to_bytes(2, "little") + bytes([3, opcode, 0, 0, 0, 0]) + bytes(4)
                since = time.monotonic()
                c.send(c.mav.file_transfer_protocol_encode(0, 1, 1,
                                                           list(request.ljust(251, b"\0"))))
                got = bytes((await c.wait("FILE_TRANSFER_PROTOCOL", since=since)).payload)
                assert int.from_bytes(got[0:2], "little") == seq + 1
                assert (got[2], got[3], got[5]) == (3, reply, opcode)
                if error is not None:
                    assert got[12] == error

    asyncio.run(main())


def test_capabilities_and_geofence_bit() -> None:
    async def main() -> None:
        async with _vehicle() as (_mock, c):
            c.command(_m.MAV_CMD_REQUEST_MESSAGE, _m.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
            caps = (await c.wait("AUTOPILOT_VERSION", since=0.0)).capabilities
            for implemented in (_m.MAV_PROTOCOL_CAPABILITY_MAVLINK2,
                                _m.MAV_PROTOCOL_CAPABILITY_MISSION_INT,
                                _m.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE,
                                _m.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY,
                                _m.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
                                _m.MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
                                _m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED):
                assert caps & implemented, implemented
            for missing in (_m.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET,
                            _m.MAV_PROTOCOL_CAPABILITY_FTP,
                            _m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT,
                            _m.MAV_PROTOCOL_CAPABILITY_TERRAIN):
                assert not caps & missing, missing
            status = await c.wait("SYS_STATUS", since=0.0)
            fence = _m.MAV_SYS_STATUS_GEOFENCE
            assert status.onboard_control_sensors_present & fence
            assert status.onboard_control_sensors_enabled & fence
            assert status.onboard_control_sensors_health & fence

    asyncio.run(main())


# ------------------------------------------------------------------------ flight modes


async def _mode(c: MavClient, mode: px4.Px4Mode) -> int:
    since = time.monotonic()
    c.command(_m.MAV_CMD_DO_SET_MODE, *mode.command_params)
    return await c.ack(_m.MAV_CMD_DO_SET_MODE, since=since)


def test_takeoff_then_rtl_as_px4() -> None:
    """NAV_TAKEOFF climbs to MIS_TAKEOFF_ALT (param7 below it is raised, as PX4 does), then
    Hold; RTL climbs to RTL_RETURN_ALT, flies home, lands (at MPC_LAND_SPEED) and disarms."""
    async def main() -> None:
        async with _vehicle(disarm_after_land=0.3) as (mock, c):
            v = mock.vehicles[0]
            c.set_param("MIS_TAKEOFF_ALT", 1.5)
            c.set_param("RTL_RETURN_ALT", 2.5)
            c.set_param("MPC_LAND_SPEED", 3.0)
            c.set_param("MPC_Z_VEL_MAX_UP", 0.8)
            await asyncio.sleep(0.2)
            since = time.monotonic()
            c.command(_m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            assert await c.ack(_m.MAV_CMD_COMPONENT_ARM_DISARM, since=since) == \
                _m.MAV_RESULT_ACCEPTED
            c.command(_m.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 1.0)
            assert await c.ack(_m.MAV_CMD_NAV_TAKEOFF, since=since) == _m.MAV_RESULT_ACCEPTED
            assert v.mode == px4.TAKEOFF
            await c.wait("STATUSTEXT", lambda m: "Using minimum takeoff altitude: 1.50 m"
                         in m.text, since=since)
            fastest_climb = 0.0

            def held() -> bool:
                nonlocal fastest_climb
                if v.mode == px4.HOLD:
                    return True
                fastest_climb = max(fastest_climb, -v.velocity_ned[2])
                return False

            await until(held, "the takeoff to end in Hold", timeout=30.0, poll=0.02)
            assert 0.5 < fastest_climb < 0.85  # MPC_Z_VEL_MAX_UP 0.8 (default 3 m/s)
            assert -v.position_ned[2] == pytest.approx(1.5, abs=0.2)
            await asyncio.sleep(0.5)
            assert -v.position_ned[2] == pytest.approx(1.5, abs=0.1)  # it holds there

            mock.model.hold(0, np.array([2.0, 1.0, -1.5]))  # somewhere away from home
            await until(lambda: np.linalg.norm(v.position_ned - [2.0, 1.0, -1.5]) <= 0.15,
                        "the vehicle held at (2, 1, -1.5)", timeout=30.0)
            since = time.monotonic()
            c.command(_m.MAV_CMD_NAV_RETURN_TO_LAUNCH)
            assert await c.ack(_m.MAV_CMD_NAV_RETURN_TO_LAUNCH, since=since) == \
                _m.MAV_RESULT_ACCEPTED
            assert v.mode == px4.RTL
            highest, far_when_up = 0.0, None

            def landed() -> bool:
                nonlocal highest, far_when_up
                if not v.armed:
                    return True
                p = v.position_ned
                highest = max(highest, -p[2])
                if far_when_up is None and -p[2] > 2.3:
                    far_when_up = float(np.hypot(p[0], p[1]))
                return False

            await until(landed, "RTL to land and disarm", timeout=40.0, poll=0.02)
            assert highest == pytest.approx(2.5, abs=0.2)
            assert far_when_up is not None and far_when_up > 1.8  # it climbed, then came back
            np.testing.assert_allclose(v.position_ned, [0.0, 0.0, 0.0], atol=0.25)
            assert "Landing detected" in c.texts()

    asyncio.run(main())


def test_position_mode_refused_without_manual_control() -> None:
    async def main() -> None:
        async with _vehicle() as (mock, c):
            assert await _mode(c, px4.POSITION) == _m.MAV_RESULT_TEMPORARILY_REJECTED
            assert mock.vehicles[0].mode == px4.HOLD
            await c.wait("STATUSTEXT", lambda m: m.text ==
                         "Switching to Position is currently not available", since=0.0)
            c.send(c.mav.manual_control_encode(1, 0, 0, 500, 0, 0))
            await asyncio.sleep(0.1)
            assert await _mode(c, px4.POSITION) == _m.MAV_RESULT_ACCEPTED
            assert mock.vehicles[0].mode == px4.POSITION
            assert await _mode(c, px4.TAKEOFF) == _m.MAV_RESULT_ACCEPTED  # AUTO.TAKEOFF too

    asyncio.run(main())


def test_refused_setpoints_are_explained_once() -> None:
    """LOCAL_OFFSET_NED and FORCE are refused with PX4's texts, each said once however often
    the setpoint comes (rate-limited)."""
    async def main() -> None:
        async with _vehicle() as (mock, c):
            offset = c.mav.set_position_target_local_ned_encode(
                0, 1, 1, _m.MAV_FRAME_LOCAL_OFFSET_NED, 0x0DF8, 1, 2, -3, 0, 0, 0, 0, 0, 0, 0, 0)
            force = c.mav.set_position_target_local_ned_encode(
                0, 1, 1, _m.MAV_FRAME_LOCAL_NED, 0x0C3F | 0x200, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0)
            for _ in range(5):
                c.send(offset)
                c.send(force)
                await asyncio.sleep(0.05)
            await asyncio.sleep(0.3)
            texts = mock.vehicles[0].statustexts  # whole texts (sent in 50-byte chunks)
            assert texts.count("SET_POSITION_TARGET_LOCAL_NED coordinate frame 7 unsupported") == 1
            assert "".join(c.texts()).count("frame 7 unsupported") == 1
            assert texts.count("SET_POSITION_TARGET_LOCAL_NED force not supported") == 1
            assert mock.vehicles[0].setpoints_ignored == 10

    asyncio.run(main())


# ------------------------------------------------------------------------------- links


def test_link_latches_its_first_partner() -> None:
    """Another process's HEARTBEAT does not pull the vehicle's traffic away from the GCS that
    spoke first (PX4's UDP link keeps its first partner)."""
    async def main() -> None:
        async with _vehicle() as (mock, c):
            v = mock.vehicles[0]
            async with MavClient(("127.0.0.1", 0), v.listen_address) as other:
                for _ in range(3):
                    other.heartbeat()
                    other.command(_m.MAV_CMD_REQUEST_MESSAGE, 0.0)
                    await asyncio.sleep(0.2)
                since = time.monotonic()
                await asyncio.sleep(1.2)
                assert other.received == []  # not even the ACKs of its own requests
                assert c.messages("HEARTBEAT", since)  # the first GCS still gets everything
                assert len(c.messages("COMMAND_ACK", since - 1.0)) >= 1
                assert v.links[0].partner == v.gcs_address

    asyncio.run(main())


def test_gcs_link_beside_the_offboard_link() -> None:
    """With a GCS link a ground station on its port gets the vehicle's telemetry and answers
    to its own requests there, and the offboard GCS does not get those answers."""
    async def main() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind(("127.0.0.1", 0))
            gcs_port = probe.getsockname()[1]
        async with _vehicle(gcs_link_port=gcs_port) as (mock, c):
            v = mock.vehicles[0]
            assert [link.name for link in v.links] == ["offboard", "gcs"]
            gcs_link = v.links[1]
            async with MavClient(("127.0.0.1", gcs_port), gcs_link.local_address) as qgc:
                await qgc.wait("HEARTBEAT", since=0.0)
                since = time.monotonic()
                qgc.send(qgc.mav.param_request_read_encode(1, 1, b"MAV_SYS_ID", -1))
                got = await qgc.wait("PARAM_VALUE", since=since)
                assert got.param_id == "MAV_SYS_ID"
                qgc.send(qgc.mav.param_request_list_encode(1, 1))  # streamed over many ticks
                await qgc.wait("PARAM_VALUE", lambda m: m.param_index == len(PX4_PARAMS) - 1,
                               since=since)
                assert len(qgc.messages("PARAM_VALUE", since)) == len(PX4_PARAMS) + 2
                assert not c.messages("PARAM_VALUE", since)  # the replies went on its link
                await c.wait("HEARTBEAT", since=since)  # telemetry goes on both links
                assert gcs_link.partner == ("127.0.0.1", gcs_port)

    asyncio.run(main())


# ---------------------------------------------------------------------------- geofence


def test_geofence_rule_as_px4() -> None:
    """Inside one inclusion shape at least (when there are any), outside every exclusion one,
    within GF_MAX_HOR_DIST / GF_MAX_VER_DIST."""
    from gcs.sim.geofence import Geofence
    from gcs.sim.missions import FenceShape

    origin = DEFAULT_WORLD_ORIGIN
    m_lat, m_lon = 1 / 111_195.0, 1 / (111_195.0 * math.cos(math.radians(origin.lat)))
    square = FenceShape(True, tuple((origin.lat + n * m_lat, origin.lon + e * m_lon)
                                    for n, e in ((-10, -10), (10, -10), (10, 10), (-10, 10))))
    hole = FenceShape(False, ((origin.lat + 5 * m_lat, origin.lon),), 2.0)
    far_circle = FenceShape(True, ((origin.lat + 30 * m_lat, origin.lon),), 3.0)
    fence = Geofence(origin)
    fence.load([square, hole, far_circle])

    def inside(n: float, e: float, up: float = 2.0, max_h: float = 0.0,
               max_v: float = 0.0) -> bool:
        return fence.inside(np.array([n, e, -up]), max_h, max_v)

    assert inside(0, 0) and inside(9, -9) and inside(30, 1)  # in the square, in the circle
    assert not inside(11, 0) and not inside(0, -11)  # outside every inclusion
    assert not inside(5, 0.5)  # in the exclusion circle
    assert not inside(0, 0, max_h=0.0, max_v=1.5)  # above GF_MAX_VER_DIST
    assert not inside(9, 0, max_h=8.0)  # beyond GF_MAX_HOR_DIST
    empty = Geofence(origin)
    assert empty.inside(np.array([1e3, 1e3, -50.0]), 0.0, 0.0)


def test_geofence_breach_holds_and_is_reported() -> None:
    """A vehicle leaving its inclusion circle with GF_ACTION 2: PX4's warning, Hold at the last
    point inside, SYS_STATUS geofence unhealthy until it is back inside."""
    async def main() -> None:
        async with _vehicle() as (mock, c):
            v = mock.vehicles[0]
            o = v.origin
            circle = [(_m.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, 4.0, o.lat, o.lon)]
            assert await _upload(c, _FENCE, circle) == _m.MAV_MISSION_ACCEPTED
            c.set_param("MIS_TAKEOFF_ALT", 1.0)
            await asyncio.sleep(0.2)
            c.command(_m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            c.command(_m.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
            await until(lambda: v.mode == px4.HOLD and v.in_air, "the takeoff", timeout=30.0)
            assert not v.fence_breached
            mock.model.hold(0, np.array([8.0, 0.0, -1.0]))  # out of the 4 m circle
            await until(lambda: v.mode != px4.HOLD or v.fence_breached, "the fence breach",
                        timeout=30.0, poll=0.02)
            since = time.monotonic()
            await c.wait("STATUSTEXT", lambda m: m.text == "Approaching on Geofence",
                         since=since - 1.0)
            status = await c.wait("SYS_STATUS", since=since)
            assert not status.onboard_control_sensors_health & _m.MAV_SYS_STATUS_GEOFENCE
            assert v.mode == px4.HOLD
            await asyncio.sleep(2.5)  # held at the last point inside: back within the circle
            assert np.hypot(*v.position_ned[:2]) < 4.2
            assert not v.fence_breached
            status = await c.wait("SYS_STATUS", since=time.monotonic())
            assert status.onboard_control_sensors_health & _m.MAV_SYS_STATUS_GEOFENCE

    asyncio.run(main())
