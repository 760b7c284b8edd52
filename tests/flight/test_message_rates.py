"""message_rates: request: the GCS asks each vehicle for what it reads, at the rates it needs
(MAV_CMD_SET_MESSAGE_INTERVAL), and turns PX4's fast streams it never reads off."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.sim import MockFleet, homes_under
from gcs.wire import mavlink
from tests.flight.support import FAST_MOCK, QUICK, mock_ports, short_line, smooth_plan

pytestmark = pytest.mark.timeout(120)

LPN = mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED


@pytest.mark.flight
def test_requested_position_rate_is_what_arrives() -> None:
    plan = smooth_plan(short_line(2))
    options = QUICK.replace(message_rates="request", position_rate_hz=50.0)

    async def fly():
        homes = homes_under(plan.scenario.starts)
        async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(2),
                             **FAST_MOCK) as mock:
            assert mock.vehicles[0].intervals[LPN] == pytest.approx(1 / 30)
            fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
            record = await FlightExecutor(plan, fleet, options).run()
            return record, mock

    record, mock = asyncio.run(fly())
    assert record["summary"]["completed"] is True
    answers = [e for e in record["events"] if e["kind"] == "message_rates"]
    assert sorted(e["vehicle"] for e in answers) == ["uav1", "uav2"]
    for e in answers:
        assert "LOCAL_POSITION_NED 50 Hz ACCEPTED" in e["detail"]
        assert "ATTITUDE off ACCEPTED" in e["detail"]
    assert all(v.intervals[LPN] == pytest.approx(0.02) for v in mock.vehicles)
    # and position reports kept arriving while the plan was flown (the rate that arrives is
    # bench/stream.py's figure: a starved machine delivers less)
    t0, horizon = record["flight_start"], record["horizon"]
    for v in record["vehicles"]:
        t = np.asarray(v["telemetry"]["t"])
        assert np.count_nonzero((t >= t0) & (t <= t0 + horizon)) > 0



def test_what_is_turned_off_is_never_what_the_gcs_decodes() -> None:
    """`message_rates: request` turns UNREAD_STREAMS off; none of them may be a message the
    link reads (DECODED_IDS), or the GCS would switch off its own telemetry."""
    from gcs.autopilot.px4 import PX4, UNREAD_STREAMS
    from gcs.flight.link.link import DECODED_IDS

    # TIMESYNC's stream is the vehicle's own requests; the answers the link reads are not
    # streamed, so turning the stream off keeps them
    timesync = {mavlink.MAVLINK_MSG_ID_TIMESYNC}
    assert (DECODED_IDS - timesync).isdisjoint(UNREAD_STREAMS)
    asked = PX4.message_rates(30.0)
    assert all(hz > 0 for mid, hz in asked.items() if mid in DECODED_IDS - timesync)
    assert all(asked.get(mid, 0.0) <= 0 for mid in UNREAD_STREAMS)
