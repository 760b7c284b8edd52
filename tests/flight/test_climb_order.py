"""Vehicles whose climbs would pass through each other climb in waves, the higher start first
(`gcs.flight.run.climb_order`): the order itself, and a flight on mocks set down under two
starts 0.55 m apart horizontally (R = 1 m) that keeps R - 0.05 m in truth while both fly."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from gcs.flight.run.climb_order import climb_waves
from gcs.phases import EventKind
from gcs.sim import MockFleet
from tests.flight.flying import fly_on_mocks
from tests.flight.support import STACKED, smooth_plan
from tests.support.waiting import ENDED, every, until

pytestmark = pytest.mark.timeout(120)


def test_the_higher_start_climbs_first_and_clear_columns_climb_at_once() -> None:
    homes = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.9, 0.0, 0.0], [5.0, 0.0, 0.0],
             [0.2, 0.3, 0.0]]
    starts = [[0.0, 0.0, 1.0], [0.5, 0.0, 3.0], [0.9, 0.0, 2.0], [5.0, 0.0, 1.0],
              [0.2, 0.3, 0.0]]  # the last stays on the ground: it does not climb
    # 1 (3 m) first; 2 (2 m) under it next; 0 (1 m) under both last; 3 far off at once
    assert climb_waves(homes, starts, 1.0) == [2, 0, 1, 0, 0]
    assert climb_waves(homes, starts, 0.3) == [0, 0, 0, 0, 0]  # every column R apart
    # the separation metric's scale: 0.5 m in x is 1.0 in a metric that doubles x
    assert climb_waves(homes[:2], starts[:2], 1.0, scale=(0.5, 1.0, 1.0)) == [0, 0]


@pytest.mark.flight
def test_stacked_columns_climb_in_waves_and_keep_r() -> None:
    """STACKED on mocks under its starts: "high" climbs to 1.92 m first, "low" leaves the
    ground only once it is up, and the two stay R - 0.05 m apart in truth while both are in
    the air (their homes are 0.55 m apart: on the ground they are nearer)."""
    plan = smooth_plan(STACKED)
    truth: list[np.ndarray] = []

    async def sample(flight: Any, mock: MockFleet) -> None:
        sampler = asyncio.create_task(every(0.01, lambda: truth.append(
            np.array([v.true_position_world for v in mock.vehicles]))))
        await until(lambda: flight.phase in ENDED, "the flight's end", timeout=90.0, poll=0.01)
        sampler.cancel()

    _, record, _ = asyncio.run(fly_on_mocks(plan, during=sample))
    assert isinstance(record, dict) and record["summary"]["completed"], record
    events = [(e["vehicle"], e["kind"], e["detail"]) for e in record["events"]]
    assert ("low", EventKind.CLIMB, "climbs in wave 2 of 2: a vehicle with a higher start "
            "stands nearer than R to its column") in events
    up = next(n for n, (v, k, _) in enumerate(events) if v == "high" and k == EventKind.AT_START)
    armed = next(n for n, (v, k, _) in enumerate(events) if v == "low" and k == EventKind.ARMED)
    assert up < armed  # "low" was armed only once "high" stood at its start
    airborne = [p for p in truth if np.all(p[:, 2] > 0.05)]  # both off the ground
    assert len(airborne) > 100
    closest = min(float(np.linalg.norm(p[0] - p[1])) for p in airborne)
    assert closest >= plan.scenario.min_separation - 0.05
