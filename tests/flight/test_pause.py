"""Pause and resume a flight on mock vehicles: the shared flight clock stops, every vehicle
holds the plan's setpoint of the same plan time (so the fleet stays as separated as the plan),
then the flight resumes from there and completes; a pause that lasts too long ends the flight."""

from __future__ import annotations

import asyncio
import itertools
import time

import numpy as np
import pytest

from gcs.errors import FlightAborted, StateConflict
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.run.executor import TRACKING_TOLERANCE_M, FlightExecutor
from gcs.flight.run.record import plan_times
from gcs.phases import EventKind
from gcs.sim import MockFleet, homes_under
from tests.flight.support import FAST_MOCK, line_scenario, mock_ports, smooth_plan
from tests.support.waiting import reached, until

pytestmark = pytest.mark.timeout(120)

FAST = FlightOptions(hold_at_goal=1.0, prestream=0.3, climb_speed=2.0)
#: Three vehicles 1.2 m apart (R = 1 m) flying side by side: a pause must keep them apart.
CLOSE = line_scenario(3, spacing=1.2)


async def _fly(plan, options, during):
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(len(homes)),
                         **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, options)
        task = flight.start()
        await during(flight, mock)
        try:
            outcome = await task
        except Exception as exc:
            outcome = exc
        return flight, outcome


@pytest.mark.flight
def test_paused_fleet_holds_still_and_separated_then_completes() -> None:
    plan = smooth_plan(CLOSE)
    r = plan.scenario.min_separation
    seen: dict[str, object] = {}

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        with pytest.raises(StateConflict):
            flight.resume()  # nothing to resume
        # mid-plan, every vehicle moving: a busy machine starves the in-process mock, whose
        # vehicles then trail the plan, so wait for the motion itself, not a plan time
        await reached(flight, 2.0)

        def moving() -> bool:
            assert flight.flight_time() < plan.scenario.horizon, "never moving"
            return min(np.linalg.norm(v.velocity_ned) for v in mock.vehicles) > 0.3

        await until(moving, "every vehicle moving faster than 0.3 m/s", timeout=60.0,
                    poll=0.02)
        t_pause = flight.pause()
        paused_at = time.monotonic()
        seen["t_pause"] = t_pause
        assert flight.snapshot()["phase"] == "paused"
        with pytest.raises(StateConflict, match="already paused"):
            flight.pause()
        # the vehicles brake, overshoot a little and settle on the held setpoint (PX4's
        # position gain of about 1/s: a few seconds)
        held = plan.sample([t_pause]).position[:, 0]

        def settled() -> bool:
            where = np.stack([v.position_world for v in mock.vehicles])
            return (max(np.linalg.norm(v.velocity_ned) for v in mock.vehicles) < 0.01
                    and float(np.max(np.linalg.norm(where - held, axis=1))) < 0.03)

        await until(settled, "the paused fleet to settle on the held setpoint", timeout=60.0)
        assert flight.flight_time() == pytest.approx(t_pause)  # the clock stands still
        before = np.stack([v.position_world for v in mock.vehicles])
        distances = []
        for _ in range(10):
            await asyncio.sleep(0.1)
            now = np.stack([v.position_world for v in mock.vehicles])
            distances += [float(np.linalg.norm(now[i] - now[j]))
                          for i, j in itertools.combinations(range(3), 2)]
        after = np.stack([v.position_world for v in mock.vehicles])
        # still: nobody moved more than 3 cm in the last second of the pause
        assert np.max(np.linalg.norm(after - before, axis=1)) < 0.03
        # every vehicle holds the plan's position of the same plan time
        np.testing.assert_allclose(after, held, atol=0.06)
        # and the fleet stays separated as the plan is
        assert min(distances) >= r - TRACKING_TOLERANCE_M
        assert flight.flight_time() == pytest.approx(t_pause)
        assert flight.resume() == pytest.approx(t_pause)
        seen["paused_for"] = time.monotonic() - paused_at
        assert flight.snapshot()["phase"] == "flying"

    _flight, record = asyncio.run(_fly(plan, FAST, during))
    assert isinstance(record, dict), record
    summary = record["summary"]
    assert summary["completed"] is True, summary
    assert summary["goal_error_max"] < 0.2
    assert summary["min_separation_measured"] >= r - TRACKING_TOLERANCE_M
    # the one pause recorded as long as it lasted, and the tracking error is measured
    # against the plan's time (the clock stood still), not the wall clock: small (on the
    # wall clock the held vehicles would be over 1 m behind). A stall of the station (a
    # busy machine: the in-process mock stalls with it) lets them trail the plan meanwhile,
    # which the record says.
    [[start, end]] = record["pauses"]
    assert end - start == pytest.approx(seen["paused_for"], abs=0.25)
    stalled = any(e["kind"] == EventKind.STATION_STALL for e in record["events"])
    assert summary["tracking_error_max"] < (FAST.tracking_error_max if stalled else 0.3)
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index("pause") < kinds.index("resume") < kinds.index("horizon")
    # the horizon came pause-length later than without the pause
    horizon = next(e["t"] for e in record["events"] if e["kind"] == "horizon")
    assert horizon - record["flight_start"] >= plan.scenario.horizon + (end - start) - 0.1


@pytest.mark.flight
def test_a_pause_longer_than_the_limit_lands_the_fleet() -> None:
    plan = smooth_plan(line_scenario(2))

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await reached(flight, 1.5)
        flight.pause()

    options = FAST.replace(pause_limit=1.0, pause_expiry="land")
    flight, outcome = asyncio.run(_fly(plan, options, during))
    assert isinstance(outcome, FlightAborted)
    assert "paused longer than 1 s" in str(outcome)
    record = flight.record
    assert record is not None
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index("pause") < kinds.index("pause_limit") < kinds.index("abort")
    assert {e["vehicle"] for e in record["events"] if e["kind"] == "landed"} == {"uav1", "uav2"}
    [[start, end]] = record["pauses"]
    assert end is not None and 0.9 <= end - start < 3.0


def test_plan_times_stop_during_pauses() -> None:
    t = np.array([10.0, 12.0, 13.0, 15.0, 20.0])
    # flight started at 10; paused from 12 to 14 and from 18 (still paused)
    np.testing.assert_allclose(plan_times(t, 10.0, [[12.0, 14.0], [18.0, None]]),
                               [0.0, 2.0, 2.0, 3.0, 6.0])
