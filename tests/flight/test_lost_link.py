"""A vehicle whose link is lost mid-flight is a moving obstacle for the landing plan.

Its link is blackholed both ways (the mock drops every packet in and out), so the station
neither hears it nor reaches it: it flies PX4's own offboard-loss failsafe (the mock's
PX4 timings: 1 s without setpoints, Position hold for COM_FAIL_ACT_T = 5 s, then Land). The
policy land_all lands the others by a verified plan that keeps R + a margin from its
predicted failsafe motion; the true separation, read from the mocks' own state, stays
>= R - 0.05 m until every vehicle is down.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import planner
from gcs.autopilot import px4
from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety import landing as landing_module
from gcs.phases import EventKind
from gcs.sim import MockFleet
from gcs.sim.fleet import homes_under
from planner.methods.landing import LandingError, LandingPlan, plan_landing
from tests.flight.support import FAST_MOCK, QUICK, mock_ports
from tests.support.waiting import every, reached, until

pytestmark = pytest.mark.timeout(180)

EXAMPLES = Path(__file__).resolve().parents[2] / "planner" / "examples"
#: The station's options: land_all, the mock's landing speed (FAST_MOCK's MPC_LAND_SPEED),
#: a landing-plan bound a busy machine meets (planned in about 0.05 s), short enough that the
#: others do not fly on long along the plan the lost vehicle has left.
OPTIONS = QUICK.replace(policy="land_all", land_speed=FAST_MOCK["land_speed"],
                        landing_plan_timeout=1.0)


def _plan(name: str, steps: int) -> planner.Plan:
    data = json.loads((EXAMPLES / f"{name}.json").read_text())
    plan = planner.plan(planner.Scenario.from_dict({**data, "steps": steps}))
    assert plan.ok, plan.problems()
    return plan


@pytest.fixture(scope="module")
def circle4() -> planner.Plan:
    return _plan("paper-circle4", 60)


async def _blackhole(plan: planner.Plan, lost: int, at: float
                     ) -> tuple[FlightExecutor, Any, list[np.ndarray], MockFleet]:
    """Fly `plan`, blackhole vehicle `lost` at flight time `at`; the true positions of all
    vehicles from then until the flight has ended and every vehicle is disarmed."""
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(len(homes)),
                         **FAST_MOCK) as mock:
        assert mock.vehicles[lost].config.failsafe_action_delay == px4.COM_FAIL_ACT_T_S
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, OPTIONS)
        task = flight.start()
        await reached(flight, at)
        truth: list[np.ndarray] = []
        mock.vehicles[lost].faults.loss = 1.0  # nothing in, nothing out
        # every vehicle's true position every 10 ms, read at one instant in the mock's loop
        sampler = asyncio.create_task(every(0.01, lambda: truth.append(
            np.array([v.true_position_world for v in mock.vehicles]))))
        try:
            outcome: Any = await task
        except Exception as exc:
            outcome = exc
        # the lost one lands on its own, later, or hovers on its Hold failsafe (its column
        # meets another's)
        await until(lambda: not any(v.armed and v.mode != px4.HOLD for v in mock.vehicles),
                    "every vehicle disarmed or holding", timeout=60.0, poll=0.01,
                    detail=lambda: [(v.armed, v.mode) for v in mock.vehicles])
        sampler.cancel()
        return flight, outcome, truth, mock


def _closest(truth: list[np.ndarray], scale: np.ndarray) -> float:
    """Smallest true pair distance (the plan's metric) over the samples."""
    i, j = np.triu_indices(truth[0].shape[0], k=1)
    return min(float(np.min(np.linalg.norm((p[i] - p[j]) / scale, axis=1))) for p in truth)


def _check(flight: FlightExecutor, outcome: Any, truth: list[np.ndarray], mock: MockFleet,
           plan: planner.Plan, lost: str, plans: int = 1) -> list[str]:
    """The lost vehicle planned around by `plans` landing plans (their events returned),
    nobody sent straight down unplanned, everyone down, R - 0.05 m kept in truth."""
    record = flight.record
    assert record is not None and not isinstance(outcome, dict), outcome
    told = [(e["vehicle"], e["kind"], e["detail"]) for e in record["events"]]
    assert (lost, EventKind.FAULT) in [(v, k) for v, k, _ in told]
    landings = [d for _, k, d in told if k == EventKind.LANDING_PLAN]
    assert len(landings) == plans, landings
    assert all(f"around {lost}" in d for d in landings)  # around its predicted failsafe
    # never sent straight down unplanned (a busy machine may miss the first plan's bound:
    # the others then hold, and the next plan lands them)
    assert not any(k == EventKind.LANDING_FALLBACK and (v not in (None, lost)
                                                        or d.startswith("PX4 Land"))
                   for v, k, d in told), told
    gone = mock.vehicles[plan.scenario.ids.index(lost)]
    hold = gone.config.offboard_loss_action == px4.OBL_HOLD  # its column meets another's
    for vehicle in mock.vehicles:  # all down, the lost one by its own failsafe, or hovering
        if vehicle is gone and hold:
            assert vehicle.armed and vehicle.mode == px4.HOLD
            continue
        assert not vehicle.armed and vehicle.true_position_world[2] < 0.05
    assert any(f"failsafe: {'Hold' if hold else 'Land'}" in what for _, what in gone.events)
    r = plan.scenario.min_separation
    assert len(truth) > 200  # every 10 ms of some 10 s (fewer on a busy machine)
    assert _closest(truth, np.asarray(plan.scenario.separation_scale)) >= r - 0.05
    return landings


@pytest.mark.flight
@pytest.mark.parametrize("at", [3.0, 5.5])
def test_landing_plan_keeps_clear_of_a_lost_vehicle(circle4: planner.Plan, at: float) -> None:
    """paper-circle4 (12 s), uav2's link blackholed at `at` s (before and in the crossing):
    land_all's landing plan keeps R from uav2's predicted failsafe descent."""
    flight, outcome, truth, mock = asyncio.run(_blackhole(circle4, 1, at))
    _check(flight, outcome, truth, mock, circle4, "uav2")


@pytest.mark.flight
def test_where_no_landing_keeps_clear_the_others_move_away_first(
        circle4: planner.Plan, monkeypatch: pytest.MonkeyPatch) -> None:
    """paper-circle4, uav2 lost at 5.5 s as it passes over uav1 (0.71 m apart horizontally
    at 5.9 s). The straight landing is refused here, as where no landing keeps R: the
    others first fly a verified plan away from uav2's predicted column at their own
    heights, then land by a plan from there; R - 0.05 m kept in truth until touchdown."""
    escaped: list[bool] = []

    def no_landing_before_moving_away(*args: Any, **kwargs: Any) -> LandingPlan:
        if kwargs["stages"] == ("landing",) and not escaped:
            raise LandingError("no landing plan keeps R (refused by the test)")
        result = plan_landing(*args, **kwargs)
        escaped.append(not result.touchdown)
        return result

    monkeypatch.setattr(landing_module, "plan_landing", no_landing_before_moving_away)
    flight, outcome, truth, mock = asyncio.run(_blackhole(circle4, 1, 5.5))
    away, down = _check(flight, outcome, truth, mock, circle4, "uav2", plans=2)
    assert escaped == [True, False]
    assert "move away first" in away and "clear of their columns" in away
    assert "land by a verified plan" in down


@pytest.mark.flight
@pytest.mark.slow
@pytest.mark.parametrize(("lost", "at"), [(2, 6.0), (1, 7.0)])
def test_eight_vehicles_land_clear_of_a_lost_one(lost: int, at: float) -> None:
    """paper-circle8 (16 s), a vehicle's link blackholed as the circle closes in: the other
    seven land by a plan around its failsafe, R kept in truth. uav2 lost at 7 s leaves uav3
    and uav4 nearer than R to its predicted motion: those pairs alone start below R."""
    plan = _plan("paper-circle8", 80)
    flight, outcome, truth, mock = asyncio.run(_blackhole(plan, lost, at))
    _check(flight, outcome, truth, mock, plan, plan.scenario.ids[lost])
