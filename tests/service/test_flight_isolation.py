"""The flight runs apart from the service, in the vehicle process
(`gcs.flight.host.vehicle_process`):
a service loop blocked for 1.5 s, or the service's interpreter lock held as long, while a flight
streams delays no setpoint tick and loses no link; a vehicle process that dies fails the flight
instead of leaving it waiting."""

from __future__ import annotations

import asyncio
import ctypes
import itertools
import os
import re
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from gcs.errors import VehicleLoopStopped
from gcs.flight.host.vehicle_loop import SWITCH_INTERVAL_S, VehicleLoop
from gcs.phases import EventKind
from gcs.service.flights import FleetService, LiveFlight
from gcs.service.settings import Settings
from gcs.service.store import Store
from tests.api.support import free_udp_base
from tests.flight.support import QUICK_MOCK_SETTINGS, short_line, smooth_plan
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(180)

#: How long the test holds the service's loop (s): longer than `link_timeout` (1.5 s of
#: station-running time is a lost link for an executor on that loop) and 30 ticks at 20 Hz.
BLOCK_S = 1.5


async def _flying(service: FleetService, mission_id: str, plan: Any) -> LiveFlight:
    """Fly `plan` on the service's fleet; the live flight, once the plan's clock started."""
    row = await service.fly(mission_id, plan, {"hold_at_goal": 0.5})
    flight = service.flight(row.id)
    assert flight is not None
    await until(lambda: any(e["kind"] == EventKind.FLIGHT_START for e in flight.events),
                "the plan started")
    return flight


def _block_the_loop() -> None:
    time.sleep(BLOCK_S)  # the service's loop does nothing else meanwhile


def _hold_the_gil() -> None:
    # a C call that never releases the GIL, as a large serialisation does: a PyDLL call
    # keeps it for its whole length
    holder = threading.Thread(target=ctypes.PyDLL(None).usleep, args=(int(BLOCK_S * 1e6),))
    holder.start()
    holder.join()


@pytest.mark.flight
@pytest.mark.parametrize("block", [_block_the_loop, _hold_the_gil],
                         ids=["blocked-loop", "held-interpreter-lock"])
def test_a_busy_service_delays_no_tick_of_the_flight(tmp_path: Path,
                                                      block: Callable[[], None]) -> None:
    """The service's loop blocked for 1.5 s, or its interpreter lock held as long: the
    flight, in its own process, streams through (on a thread of the service's interpreter a
    held lock stops every tick for as long)."""
    plan = smooth_plan(short_line(2, steps=25))  # 5 s: the block falls inside the plan
    settings = Settings(mock_vehicles=2, mock_base_port=free_udp_base(2), mock_settle_s=0.5,
                        database_url=f"sqlite:///{tmp_path / 'fleet.db'}", **QUICK_MOCK_SETTINGS)
    store = Store(settings.database_url)
    mission = store.create_mission(plan.scenario.to_dict())

    async def fly() -> dict[str, Any]:
        service = FleetService(settings, store)
        await service.start()
        try:
            flight = await _flying(service, mission.id, plan)
            block()
            await asyncio.wait_for(flight.done.wait(), 120)
            assert flight.status == "completed", (flight.status, flight.error, flight.summary)
            assert flight.handle is not None and flight.handle.record is not None
            return flight.handle.record
        finally:
            await service.close()
            store.close()

    _assert_streamed_through(asyncio.run(fly()))


def _assert_streamed_through(record: dict[str, Any]) -> None:
    """The flight completed with no lost link, no setpoint gap near BLOCK_S and no station
    stall as long."""
    summary = record["summary"]
    assert summary["completed"] is True, summary["why"]
    assert not summary["faults"]  # no vehicle lost its link or left OFFBOARD
    # Setpoints kept leaving through the block: on the service's loop the stream sends
    # nothing for its 1.5 s (and misses ~30 ticks at 20 Hz).
    events = {e["kind"]: e["t"] for e in record["events"]}
    start, horizon = events[EventKind.FLIGHT_START], events[EventKind.HORIZON]
    for vehicle in record["vehicles"]:
        times = vehicle["setpoints"]["t"]
        first = next(i for i, t in enumerate(times) if t >= start)
        # from the last send before the plan started (the block may begin right after it)
        sent = [t for t in times[max(first - 1, 0):] if t <= horizon]
        gap = max(b - a for a, b in itertools.pairwise(sent))
        assert gap < BLOCK_S / 2, (vehicle["id"], gap)  # bound
    # The station noticed no stall of its own as long as the block (its stall events name
    # the longest in seconds).
    stalls = [e["detail"] for e in record["events"] if e["kind"] == EventKind.STATION_STALL]
    longest = [float(s) for d in stalls for s in re.findall(r"(?:stalled|longest) ([0-9.]+) s", d)]
    assert max(longest, default=0.0) < 1.0, stalls


def test_a_call_on_a_stopped_vehicle_loop_is_refused_not_left_waiting() -> None:
    vehicles = VehicleLoop(name="fleetplan-test-vehicles")
    vehicles.start()

    async def main() -> None:
        assert await vehicles.run(lambda: 2 + 2) == 4
        waiting = asyncio.ensure_future(vehicles.call(lambda: asyncio.sleep(3600)))
        await asyncio.sleep(0)
        await asyncio.to_thread(vehicles.stop)
        with pytest.raises(VehicleLoopStopped):
            await waiting
        with pytest.raises(VehicleLoopStopped):
            await vehicles.run(lambda: None)

    asyncio.run(main())


def test_the_vehicle_threads_scheduling_is_what_it_reports() -> None:
    """realtime: SCHED_RR 1 where Linux allows it, else ordinary with the refusal named;
    either way the report matches the thread's own policy, and the GIL switch interval is
    short only while a vehicle loop runs."""
    before = sys.getswitchinterval()
    vehicles = VehicleLoop(name="fleetplan-test-rt", realtime=True)
    vehicles.start()

    async def policy() -> int:
        return await vehicles.run(lambda: os.sched_getscheduler(0))

    try:
        assert sys.getswitchinterval() <= SWITCH_INTERVAL_S
        seen = asyncio.run(policy()) & ~os.SCHED_RESET_ON_FORK
    finally:
        vehicles.stop()
    if vehicles.scheduling == "SCHED_RR 1":
        assert seen == os.SCHED_RR
    else:
        assert vehicles.scheduling.startswith("ordinary (real-time refused: ")
        assert seen == os.SCHED_OTHER
    assert sys.getswitchinterval() == before
    # the caller's own thread keeps its scheduling
    assert os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK == os.SCHED_OTHER


@pytest.mark.flight
def test_a_vehicle_process_killed_mid_flight_fails_the_flight(tmp_path: Path) -> None:
    """The vehicle process ending (here SIGKILL) stops every stream; the service does not wait
    on it for ever: the flight is stored failed, naming the cause."""
    plan = smooth_plan(short_line(2, steps=25))
    settings = Settings(mock_vehicles=2, mock_base_port=free_udp_base(2), mock_settle_s=0.5,
                        database_url=f"sqlite:///{tmp_path / 'fleet.db'}", **QUICK_MOCK_SETTINGS)
    store = Store(settings.database_url)
    mission = store.create_mission(plan.scenario.to_dict())

    async def fly() -> str:
        service = FleetService(settings, store)
        await service.start()
        try:
            flight = await _flying(service, mission.id, plan)
            assert service.vehicle_process.pid is not None
            killed = service.vehicle_process.pid
            os.kill(killed, signal.SIGKILL)
            await asyncio.wait_for(flight.done.wait(), 60)
            assert flight.status == "failed"
            assert flight.error is not None and "vehicle process ended" in flight.error
            assert service.active is None
            # a new vehicle process watches the fleet again (its mocks start anew)
            await until(lambda: service.vehicle_process.alive
                        and service.vehicle_process.pid != killed, "a new vehicle process")
            assert [v["id"] for v in await service.vehicles()] == ["uav1", "uav2"]
            return flight.id
        finally:
            await service.close()

    flight_id = asyncio.run(fly())
    stored = store.get_flight(flight_id)
    store.close()
    assert stored is not None and stored.status == "failed"
    assert "VehicleLoopStopped" in (stored.error or "")
