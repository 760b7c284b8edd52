"""The Streamer's stall accounting and its optional real-time scheduling."""

from __future__ import annotations

import asyncio
import os
import time

import pytest

from gcs.flight.link.endpoints import UdpEndpoint
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.setpoints import hold_track
from gcs.flight.timeline.stream import STALL_S, Streamer

pytestmark = pytest.mark.timeout(30)


def _streamer(realtime: bool = False) -> Streamer:
    streamer = Streamer(50.0, realtime=realtime)
    endpoint = UdpEndpoint("udpin:127.0.0.1:9")  # never opened: sends go nowhere
    link = VehicleLink("v", endpoint, 1, 1, peer=("127.0.0.1", 9))
    streamer.assign("v", link, hold_track((0.0, 0.0, -1.0), 0.0, 50.0))
    streamer.measuring = True
    return streamer


def test_a_callback_blocking_the_loop_counts_as_a_busy_stall() -> None:
    async def main() -> Streamer:
        streamer = _streamer()
        streamer.start()
        for _ in range(8):  # our own code hogging the loop (a decode burst, a slow listener)
            await asyncio.sleep(0.07)
            time.sleep(0.03)
        await streamer.stop()
        return streamer

    streamer = asyncio.run(main())
    assert streamer.stalls["busy"] >= 4, streamer.stalls
    # late sends are recorded, never a burst of old ticks
    assert max(streamer.lateness) > STALL_S
    assert streamer.missed_ticks >= 1


def test_realtime_is_asked_for_while_streaming_and_given_back() -> None:
    before = os.sched_getscheduler(0)

    async def main() -> tuple[Streamer, int, int]:
        streamer = _streamer(realtime=True)
        streamer.start()
        await asyncio.sleep(0.1)
        during = os.sched_getscheduler(0)  # the loop's thread: this one
        # a thread started meanwhile (the API's worker threads under `serve`) is ordinary
        spawned = await asyncio.to_thread(os.sched_getscheduler, 0)
        await streamer.stop()
        return streamer, during, spawned

    streamer, during, spawned = asyncio.run(main())
    if streamer.scheduling == "SCHED_RR 1":
        assert during & ~os.SCHED_RESET_ON_FORK == os.SCHED_RR
        assert spawned == os.SCHED_OTHER
    else:  # no CAP_SYS_NICE / rtprio limit: refused, said why, nothing changed
        assert streamer.scheduling.startswith("ordinary (real-time refused")
        assert during == before
    assert os.sched_getscheduler(0) == before
    assert _streamer().scheduling == "ordinary"


def test_stream_priority_is_a_checked_flight_option() -> None:
    from gcs.fleet.fleetfile import FleetFileError, FlightOptions

    assert FlightOptions().stream_priority == "realtime"  # asked for by default
    assert FlightOptions.from_dict({"stream_priority": "realtime"}).stream_priority == \
        "realtime"
    with pytest.raises(FleetFileError, match=r"flight\.stream_priority"):
        FlightOptions.from_dict({"stream_priority": "fast"})


@pytest.mark.flight
def test_a_flight_at_realtime_priority_completes_and_says_how_it_streamed() -> None:
    from gcs.fleet.fleetfile import FleetSpec
    from gcs.flight.run.executor import FlightExecutor
    from gcs.sim import MockFleet, homes_under
    from tests.flight.support import FAST_MOCK, QUICK, mock_ports, short_line, smooth_plan

    plan = smooth_plan(short_line(2))
    options = QUICK.replace(stream_priority="realtime")
    before = os.sched_getscheduler(0)

    async def fly() -> dict:
        homes = homes_under(plan.scenario.starts)
        async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(2),
                             **FAST_MOCK) as mock:
            fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
            return await FlightExecutor(plan, fleet, options).run()

    record = asyncio.run(fly())
    assert record["summary"]["completed"] is True
    said = [e["detail"] for e in record["events"] if e["kind"] == "stream_priority"]
    assert len(said) == 1
    assert said[0] == "SCHED_RR 1" or said[0].startswith("ordinary (real-time refused")
    assert os.sched_getscheduler(0) == before  # given back after the flight
