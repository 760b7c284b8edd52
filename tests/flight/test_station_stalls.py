"""The station's own stalls are not a vehicle's fault; a vehicle's real silence still is."""

from __future__ import annotations

import asyncio
import subprocess
import time

import pytest

from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.station import StallReport, StationStalls
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.safety.monitor import vehicle_fault
from gcs.phases import EventKind, VehiclePhase
from tests.flight.fakes import fake_link, fake_vehicle
from tests.flight.flying import FAST, fly_on_mocks, monitor_of
from tests.flight.support import line_scenario, smooth_plan
from tests.support.waiting import every, reached

pytestmark = pytest.mark.timeout(120)


def test_stalls_merge_and_discount_only_their_overlap() -> None:
    stalls = StationStalls()
    heard: list[tuple[float, float]] = []
    stalls.listeners.append(lambda s, e: heard.append((s, e)))
    stalls.note(10.0, 12.0)
    stalls.note(11.5, 12.5)  # the streamer's view of the same stall
    stalls.note(20.0, 21.0)
    assert list(stalls.spans) == [(10.0, 12.5), (20.0, 21.0)]
    assert stalls.total == pytest.approx(3.5)
    assert heard == [(10.0, 12.0), (10.0, 12.5), (20.0, 21.0)]
    stalls.note(10.5, 11.0)  # inside a known stall: nothing new
    assert len(heard) == 3
    assert stalls.running(9.0, 22.0) == pytest.approx(13.0 - 3.5)
    assert stalls.age(None, 22.0) == float("inf")
    assert stalls.ended_since(20.5) == pytest.approx(1.0)


def test_stall_events_need_the_threshold_and_are_rate_limited() -> None:
    report = StallReport(threshold=0.25, every=5.0)
    assert report.add(0.0, 0.1) is None  # below the threshold
    assert "1.00 s" in (report.add(1.0, 2.0) or "")
    assert report.add(2.5, 3.0) is None  # within 5 s of the last event: kept for later
    assert report.add(2.5, 3.5) is None  # the same stall, seen longer
    text = report.add(8.0, 8.5)
    assert text == ("station stalled 2 times, longest 1.00 s, 1.50 s in all "
                    "(its own loop, not a vehicle)")
    assert report.flush(9.0) is None  # nothing pending
    assert report.count == 3


def test_a_gap_inside_a_station_stall_is_not_a_lost_link() -> None:
    options = FlightOptions()
    v = fake_vehicle(0)
    fake_link(v).alive(100.0)
    link = v.linked
    stalls = StationStalls()
    # 2 s without a message, 1.8 s of which the station itself did not run
    stalls.note(100.1, 101.9)
    assert vehicle_fault(link, options, 102.0, stalls) is None
    # the same gap without a stall is a lost link
    assert _kind(vehicle_fault(link, options, 102.0, StationStalls())) == "link_lost"
    # and station-running time keeps counting: 1.6 s of it since the last message
    assert _kind(vehicle_fault(link, options, 103.5, stalls)) == "link_lost"


def _kind(fault: tuple[str, str] | None) -> str | None:
    return None if fault is None else fault[0]


async def _feed(vehicles: list[VehicleStatus], silent: set[str]) -> None:
    """The vehicles' messages arriving at 20 Hz (those in `silent` send nothing)."""
    def arrive() -> None:
        for v in vehicles:
            if v.id not in silent:
                fake_link(v).alive()

    await every(0.05, arrive)


def test_the_station_blocked_for_two_seconds_flags_nobody() -> None:
    vehicles = [fake_vehicle(0), fake_vehicle(1)]
    faults: list[tuple[str, str, float]] = []
    stalls = StationStalls()

    async def main() -> None:
        monitor = monitor_of(vehicles, faults, stalls)
        feed = asyncio.create_task(_feed(vehicles, set()))
        done = asyncio.Event()
        task = asyncio.create_task(monitor.run(done.is_set))
        await asyncio.sleep(0.3)
        asyncio.get_running_loop().call_soon(time.sleep, 2.0)  # a callback that blocks
        await asyncio.sleep(1.0)
        done.set()
        await task
        feed.cancel()

    asyncio.run(main())
    assert faults == []
    assert stalls.total >= 1.9


def test_a_vehicle_silent_while_the_station_runs_is_a_lost_link() -> None:
    vehicles = [fake_vehicle(0), fake_vehicle(1)]
    faults: list[tuple[str, str, float]] = []
    stalls = StationStalls()
    options = FlightOptions()
    silent: set[str] = set()

    async def main() -> float:
        monitor = monitor_of(vehicles, faults, stalls, options)
        feed = asyncio.create_task(_feed(vehicles, silent))
        task = asyncio.create_task(monitor.run(lambda: bool(faults)))
        await asyncio.sleep(0.2)
        silent.add("uav2")
        went = time.monotonic()
        await asyncio.wait_for(task, 10.0)  # bound
        feed.cancel()
        return went

    went = asyncio.run(main())
    assert [(vid, kind) for vid, kind, _ in faults] == [("uav2", "link_lost")]
    # never before link_timeout of station-running time
    assert stalls.running(went, faults[0][2]) >= options.link_timeout - 0.05


def test_a_silent_vehicle_is_still_caught_across_a_station_stall() -> None:
    vehicles = [fake_vehicle(0)]
    faults: list[tuple[str, str, float]] = []
    stalls = StationStalls()

    async def main() -> None:
        monitor = monitor_of(vehicles, faults, stalls)
        fake_link(vehicles[0]).alive()
        task = asyncio.create_task(monitor.run(lambda: bool(faults)))
        await asyncio.sleep(0.5)
        asyncio.get_running_loop().call_soon(time.sleep, 2.0)
        await asyncio.wait_for(task, 10.0)  # bound

    asyncio.run(main())
    assert [kind for _, kind, _ in faults] == ["link_lost"]
    assert stalls.total >= 1.9


@pytest.mark.flight
def test_a_flight_survives_the_station_blocked_for_two_seconds() -> None:
    """The whole loop (station and in-process mock) blocks for 2 s mid-flight: the flight
    completes, and the record says the station stalled. The plan runs on 5 s after the stall,
    long enough for the vehicles to catch up with a clock that kept running."""
    plan = smooth_plan(line_scenario(2, steps=40))

    async def during(flight, mock) -> None:
        await reached(flight, 1.0)
        asyncio.get_running_loop().call_soon(time.sleep, 2.0)

    _flight, record, _mock = asyncio.run(fly_on_mocks(plan, FAST, settle=0.5, during=during))
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True, record["summary"]["why"]
    stalls = [e for e in record["events"] if e["kind"] == EventKind.STATION_STALL]
    assert stalls and "station stalled" in stalls[0]["detail"]
    assert not [e for e in record["events"] if e["kind"] == EventKind.FAULT]


@pytest.mark.flight
def test_eight_vehicles_complete_with_two_cpu_hogs_running() -> None:
    plan = smooth_plan(line_scenario(8, steps=20))
    hogs = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(2)]
    try:
        _flight, record, _mock = asyncio.run(fly_on_mocks(plan, FAST, settle=0.5))
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    assert isinstance(record, dict), record
    assert record["summary"]["completed"] is True, record["summary"]["why"]
    phases = {v["phase"] for v in _flight.snapshot()["vehicles"]}
    assert phases == {VehiclePhase.LANDED}


def test_leaving_offboard_quotes_what_px4_warned_since_arming() -> None:
    """PX4 SITL on a loaded machine: its simulated barometer and compass went stale, PX4's
    failsafe took the vehicle to Altitude mode, and the fault said only "mode is now
    ALTCTL". The detail quotes PX4's latest warnings since arming (those before arming were
    cleared when it armed), and nothing when there were none."""
    from gcs.autopilot import px4
    from gcs.flight.safety.monitor import WARNINGS_QUOTED

    options = FlightOptions()
    v = fake_vehicle(0)
    fake_link(v).alive(100.0)
    tel = v.linked.telemetry
    tel.mode = px4.decode_custom_mode(2 << 16)  # PX4's ALTCTL
    assert vehicle_fault(v.linked, options, 100.1) == ("left_offboard", "mode is now ALTCTL")
    for text in ("Preflight Fail: No valid data from Baro 0",
                 "Preflight Fail: No valid data from Compass 0",
                 "Preflight Fail: Battery unhealthy", "Failsafe activated"):
        tel.warnings.append(text)
    kind, detail = vehicle_fault(v.linked, options, 100.1) or ("", "")
    assert kind == "left_offboard" and detail.startswith("mode is now ALTCTL; PX4 warned: ")
    assert "'Failsafe activated'" in detail and "No valid data from Compass 0" in detail
    assert "Baro 0" not in detail and WARNINGS_QUOTED == 3  # the latest three only
