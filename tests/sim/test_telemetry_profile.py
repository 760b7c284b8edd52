"""The mock's offboard-link telemetry (`gcs.sim.telemetry`): PX4's message set and rates in the
``px4`` profile, MAV_CMD_SET_MESSAGE_INTERVAL like PX4, and what a GCS asking for what it needs
(`message_rates: request`) then receives."""

from __future__ import annotations

import asyncio
import socket
import time
from collections import Counter

import pytest

from gcs.autopilot.px4 import PX4
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS, VehicleLink
from gcs.flight.procedure import vehicle
from gcs.sim import MockConfig, MockFleet
from gcs.sim.telemetry import STREAMS, default_rates
from gcs.wire import mavlink, parse_datagram
from tests.flight.support import mock_ports
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(60)

M = mavlink


class Window:
    """What vehicle 0 sent during a window: ids read off the wire by a bare socket bound to
    the port it sends to (no GCS code involved), its own per-stream counters, and the length
    of the window on the mock's clock."""

    def __init__(self, wire: Counter[int], sent: Counter[int], elapsed: float) -> None:
        self.wire, self.sent, self.elapsed = wire, sent, elapsed

    def at_most(self, hz: float) -> float:
        """The most messages a stream at `hz` can send in the window: the scheduler never
        bursts (a late stream restarts from now), so one per period, plus the one at the
        start."""
        return self.elapsed * hz + 1


async def _window(mock: MockFleet, seconds: float) -> Window:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", mock.vehicles[0].gcs_port))
    sock.setblocking(False)
    v = mock.vehicles[0]
    counts: Counter[int] = Counter()
    loop = asyncio.get_running_loop()
    before, start = Counter(v.sent), mock.now()
    end = time.monotonic() + seconds
    try:
        while (left := end - time.monotonic()) > 0:
            try:
                data = await asyncio.wait_for(loop.sock_recv(sock, 4096), left)
            except TimeoutError:
                break
            for msg in parse_datagram(data).messages:
                counts[msg.get_msgId()] += 1
    finally:
        sock.close()
    return Window(counts, Counter(v.sent) - before, mock.now() - start)


def test_minimal_profile_keeps_todays_set_and_rates() -> None:
    rates = {k: v for k, v in default_rates(MockConfig()).items() if v > 0}
    assert rates == {M.MAVLINK_MSG_ID_HEARTBEAT: 1.0, M.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
                     M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
                     M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 30.0, M.MAVLINK_MSG_ID_ATTITUDE: 20.0,
                     M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 5.0, M.MAVLINK_MSG_ID_GPS_RAW_INT: 5.0,
                     M.MAVLINK_MSG_ID_HOME_POSITION: 0.2}
    px4_total = sum(default_rates(MockConfig(telemetry_profile="px4")).values())
    assert 395 <= px4_total <= 425  # PX4 SITL: about 410 messages/s
    with pytest.raises(ValueError, match="telemetry_profile"):
        default_rates(MockConfig(telemetry_profile="full"))


def test_px4_profile_sends_the_table_at_its_rates() -> None:
    """Every stream of the table at PX4's interval: configured so, never faster, and each one
    seen on the wire."""
    async def main() -> tuple[Window, dict[int, float | None]]:
        async with MockFleet(1, telemetry_profile="px4", **mock_ports(1)) as mock:
            # from the first tick, where every stream sends its first message
            return await _window(mock, 1.0), dict(mock.vehicles[0].intervals)

    window, intervals = asyncio.run(main())
    assert intervals == {s.msg_id: pytest.approx(1.0 / s.px4_hz) for s in STREAMS}
    for stream in STREAMS:
        assert 1 <= window.sent[stream.msg_id] <= window.at_most(stream.px4_hz), stream
    assert set(window.wire) == {s.msg_id for s in STREAMS}
    # the fast streams keep their order of magnitude however busy the machine (# bound)
    assert window.sent[M.MAVLINK_MSG_ID_ATTITUDE] >= 0.3 * 100.0 * window.elapsed


def test_set_message_interval_like_px4() -> None:
    async def main() -> None:
        async with MockFleet(1, telemetry_profile="px4", **mock_ports(1)) as mock, \
                LinkHub() as hub:
            link = await hub.add("v", mock.gcs_url(0), 1)
            assert await link.wait_for(lambda t: t.heartbeat_time is not None, 5.0)

            async def interval(msg_id: int, us: float) -> int:
                return await link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, (float(msg_id), us))

            assert await interval(M.MAVLINK_MSG_ID_HEARTBEAT, 100_000) == M.MAV_RESULT_FAILED
            assert await interval(M.MAVLINK_MSG_ID_WIND_COV, 100_000) == M.MAV_RESULT_FAILED
            assert await interval(M.MAVLINK_MSG_ID_ATTITUDE, -1) == M.MAV_RESULT_ACCEPTED
            assert await interval(M.MAVLINK_MSG_ID_HIGHRES_IMU, 100_000) == \
                M.MAV_RESULT_ACCEPTED
            v = mock.vehicles[0]
            assert v.intervals[M.MAVLINK_MSG_ID_ATTITUDE] is None
            assert v.intervals[M.MAVLINK_MSG_ID_HIGHRES_IMU] == pytest.approx(0.1)
            await hub.close()  # free the port for the bare counter
            window = await _window(mock, 1.1)
            assert window.wire[M.MAVLINK_MSG_ID_ATTITUDE] == 0
            assert window.sent[M.MAVLINK_MSG_ID_ATTITUDE] == 0
            assert 1 <= window.wire[M.MAVLINK_MSG_ID_HIGHRES_IMU] <= window.at_most(10.0)
            assert window.wire[M.MAVLINK_MSG_ID_HEARTBEAT] >= 1  # never stopped
            # 0: back to the default rate
            assert v.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 0) == M.MAV_RESULT_ACCEPTED
            assert v.intervals[M.MAVLINK_MSG_ID_ATTITUDE] == pytest.approx(0.01)

    asyncio.run(main())


def test_a_minimal_vehicle_starts_a_px4_stream_on_request() -> None:
    async def main() -> None:
        async with MockFleet(1, **mock_ports(1)) as mock:
            v = mock.vehicles[0]
            assert v.intervals[M.MAVLINK_MSG_ID_ODOMETRY] is None
            assert v.set_interval(M.MAVLINK_MSG_ID_ODOMETRY, 50_000) == M.MAV_RESULT_ACCEPTED
            assert v.intervals[M.MAVLINK_MSG_ID_ODOMETRY] == pytest.approx(0.05)
            window = await _window(mock, 0.5)
            assert 1 <= window.wire[M.MAVLINK_MSG_ID_ODOMETRY] <= window.at_most(20.0)

    asyncio.run(main())


def test_a_gcs_requesting_its_rates_receives_only_what_it_needs() -> None:
    """`request_message_rates(message_rates(30))` on a PX4-rate vehicle: every answer ACCEPTED,
    then the vehicle streams only the ids the GCS reads, about 37 messages/s instead of 410,
    and only those arrive; the link counts no loss and, with `DECODED_IDS`, skips nothing
    because nothing unread is left."""
    async def main() -> tuple[dict[str, str], Counter[str], VehicleLink, int,
                              dict[int, float | None]]:
        async with MockFleet(1, telemetry_profile="px4", **mock_ports(1)) as mock, \
                LinkHub(decode_ids=DECODED_IDS) as hub:
            link = await hub.add("v", mock.gcs_url(0), 1)
            assert await link.wait_for(lambda t: t.heartbeat_time is not None, 5.0)
            await asyncio.sleep(0.3)
            assert link.telemetry.skipped > 50  # PX4's full set: unread ids are skipped
            answers = await vehicle.request_message_rates(link, PX4.message_rates(30.0))
            await asyncio.sleep(0.3)  # what was in flight
            seen: Counter[str] = Counter()
            link.listeners.append(lambda _l, m, _t: seen.__setitem__(m.get_type(),
                                                                     seen[m.get_type()] + 1))
            skipped = link.telemetry.skipped
            await asyncio.sleep(1.0)
            return (answers, seen, link, link.telemetry.skipped - skipped,
                    dict(mock.vehicles[0].intervals))

    answers, seen, link, skipped_after, intervals = asyncio.run(main())
    assert all(a.endswith("ACCEPTED") for a in answers.values()), answers
    for msg_id, hz in PX4.message_rates(30.0).items():
        assert intervals[msg_id] == (None if hz <= 0 else pytest.approx(1.0 / hz)), msg_id
    streaming = {i: 1.0 / p for i, p in intervals.items() if p is not None}
    assert set(streaming) <= DECODED_IDS
    assert 30 <= sum(streaming.values()) <= 45  # about 37/s
    assert skipped_after == 0
    assert set(seen) <= {M.mavlink_map[i].msgname for i in DECODED_IDS}
    assert seen["LOCAL_POSITION_NED"] > 0
    tel = link.telemetry
    assert tel.seq_lost <= 0.01 * tel.seq_received


def test_link_loss_stays_zero_at_px4_rates_with_skipping() -> None:
    async def main() -> VehicleLink:
        async with MockFleet(2, telemetry_profile="px4", **mock_ports(2)) as mock, \
                LinkHub(decode_ids=DECODED_IDS) as hub:
            link = await hub.add("v", mock.gcs_url(1), 2)
            # ~370/s of unread ids: 2 s on a quiet machine, longer on a busy one
            await until(lambda: link.telemetry.skipped > 500, "500 unread messages skipped",
                        timeout=45.0, poll=0.1)
            return link

    link = asyncio.run(main())
    tel = link.telemetry
    assert tel.skipped > 500
    assert tel.seq_received > tel.skipped
    assert tel.seq_lost <= 0.005 * tel.seq_received, (tel.seq_lost, tel.seq_received)
