"""Aborts with land fly a verified landing plan (`gcs.flight.safety.landing`) on the ideal mock."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.phases import EventKind
from gcs.sim import MockFleet
from tests.flight.support import FAST_MOCK, QUICK, STACKED, mock_ports, smooth_plan
from tests.flight.support import STACKED_HOMES as HOMES
from tests.support.waiting import every, reached

pytestmark = pytest.mark.timeout(120)

#: Homes apart, so the climbs (vertical, then horizontal) keep R too.


async def _sample_truth(mock: MockFleet, pairs: list[float]) -> None:
    """Append the two mock vehicles' true distance every 10 ms: both read at one instant
    in the mock's own loop, so a busy machine delays samples but never skews one vehicle's
    against the other's (telemetry stamped on arrival at the GCS can be)."""
    def sample() -> None:
        a, b = (v.true_position_world for v in mock.vehicles)
        pairs.append(float(np.linalg.norm(a - b)))

    await every(0.01, sample)


async def _abort_at(plan, t_abort: float, options):
    async with MockFleet(homes=HOMES, settle_time=0.5, **mock_ports(2), **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, options)
        task = flight.start()
        await reached(flight, t_abort)
        truth: list[float] = []
        sampler = asyncio.create_task(_sample_truth(mock, truth))
        await flight.abort("land", "test abort")
        try:
            outcome = await task
        except Exception as exc:
            outcome = exc
        sampler.cancel()
        return flight, outcome, mock, truth


@pytest.mark.flight
def test_stacked_pair_aborted_with_land_keeps_r_until_down() -> None:
    """The 0.53 m case: aborted with land while stacked, the two vehicles fly a
    verified landing plan to touchdown points R apart and PX4 lands them from there; the
    flown separation stays >= R - 0.05 m until both are on the ground, disarmed."""
    plan = smooth_plan(STACKED)
    # a bound a busy machine always meets (the plan takes milliseconds; 0.5 s by default)
    options = QUICK.replace(landing_plan_timeout=2.0)
    flight, outcome, mock, truth = asyncio.run(_abort_at(plan, 1.0, options))
    record = flight.record
    assert record is not None and not isinstance(outcome, dict)
    kinds = [e["kind"] for e in record["events"]]
    assert EventKind.LANDING_PLAN in kinds, record["events"]
    assert EventKind.LANDING_FALLBACK not in kinds
    assert len(truth) > 100  # sampled from the abort to touchdown and disarm
    assert min(truth) >= 1.0 - 0.05
    # both are down and disarmed, R apart on the ground (not one above the other)
    for vehicle in mock.vehicles:
        assert not vehicle.armed
        assert vehicle.position_world[2] == pytest.approx(0.0, abs=0.05)
    ground = [v.position_world[:2] for v in mock.vehicles]
    assert np.linalg.norm(ground[0] - ground[1]) >= 1.0 - 0.05
    assert all(e["kind"] != "not_disarmed" for e in record["events"])


async def _fly_to_the_end(plan, options):
    async with MockFleet(homes=HOMES, settle_time=0.5, **mock_ports(2), **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, options)
        task = flight.start()
        await reached(flight, plan.scenario.horizon)
        truth: list[float] = []
        sampler = asyncio.create_task(_sample_truth(mock, truth))
        record = await task
        sampler.cancel()
        return record, mock, truth


@pytest.mark.flight
def test_goals_stacked_above_each_other_land_by_a_plan_at_the_end() -> None:
    """The plan ends with the pair stacked (0.55 m apart horizontally): at_end land sends
    them down by a verified landing plan, not straight down onto each other, and the
    completed flight keeps R - 0.05 m until both are down and disarmed."""
    plan = smooth_plan(STACKED)
    options = QUICK.replace(landing_plan_timeout=2.0)
    record, mock, truth = asyncio.run(_fly_to_the_end(plan, options))
    assert record["summary"]["completed"] is True, record["summary"]
    kinds = [e["kind"] for e in record["events"]]
    assert EventKind.LANDING_PLAN in kinds, record["events"]
    assert EventKind.LANDING_FALLBACK not in kinds
    assert len(truth) > 100 and min(truth) >= 1.0 - 0.05
    for vehicle in mock.vehicles:
        assert not vehicle.armed
    ground = [v.position_world[:2] for v in mock.vehicles]
    assert np.linalg.norm(ground[0] - ground[1]) >= 1.0 - 0.05
