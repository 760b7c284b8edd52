"""Where the others hold while a vehicle is silent, and the controller model that predicts it.

The flights themselves (a blackholed vehicle, R kept in truth) are in test_lost_link.py;
these check the parts: the cascade against the mock's own controller, the hold's choice on
paper-circle8 where a silent vehicle's straight line cuts a neighbour's curve, and the clock
holding a plan tick other than the one reached.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import planner
from gcs.flight.replan.cascade import STEP_S, follow
from gcs.flight.safety.silence import HOLD_WINDOW_S, silent_hold
from gcs.flight.timeline.clock import FlightClock
from gcs.sim.model import FleetModel

EXAMPLES = Path(__file__).resolve().parents[2] / "planner" / "examples"
RATE = 50.0


@pytest.fixture(scope="module")
def circle8() -> planner.Plan:
    data = json.loads((EXAMPLES / "paper-circle8.json").read_text())
    plan = planner.plan(planner.Scenario.from_dict({**data, "steps": 80}))
    assert plan.ok, plan.problems()
    return plan


def test_the_cascade_flies_a_stale_setpoint_as_the_mock_controller_does() -> None:
    """A vehicle left with the setpoint (p, v) it was tracking: the station's model and the
    mock's controller (thrust lag, limits) agree within 2 cm over 3 s, and both end near
    p + v / 0.95 (the position gain), not at p."""
    p, v = np.array([3.0, 2.0, -1.5]), np.array([-0.4, -0.6, 0.0])
    model = FleetModel(1)
    model.powered[:] = True
    model.position[0], model.velocity[0] = p, v
    model.position_sp[0], model.velocity_sp[0] = p, v
    steps = round(3.0 / STEP_S)
    mock = [model.position[0].copy()]
    for _ in range(steps):
        for _ in range(4):
            model.step(STEP_S / 4)
        mock.append(model.position[0].copy())
    predicted, _ = follow(p, v, p, v, steps)
    assert np.max(np.linalg.norm(predicted - np.array(mock), axis=1)) < 0.02
    assert np.linalg.norm(predicted[-1] - (p + v / 0.95)) < 0.08
    assert np.linalg.norm(predicted[-1] - p) > 0.6


def _state(plan: planner.Plan, t: float) -> tuple[np.ndarray, np.ndarray]:
    sample = plan.sample(np.array([t]))
    return sample.position[:, 0], sample.velocity[:, 0]


def _room(plan: planner.Plan, lost: np.ndarray, held: list[int], p: np.ndarray,
          v: np.ndarray, t: float) -> float:
    """The closest the held vehicles come to `lost` (T, 3) holding the plan at `t`."""
    targets = _state(plan, t)[0][held]
    paths, _ = follow(p[held], v[held], targets, 0.0, lost.shape[0] - 1)
    return float(np.linalg.norm(paths - lost[:, None, :], axis=2).min())


def test_the_hold_keeps_more_room_from_a_silent_vehicle_than_stopping_where_it_is(
        circle8: planner.Plan) -> None:
    """uav2 silent from 7.0 s of paper-circle8 (R = 1 m), noticed at 7.5 s: holding the plan
    where the flight is leaves a neighbour within 0.9 m of uav2's straight flight on its
    last setpoint; the chosen hold (within the window) keeps at least 0.98 m."""
    lost_index, heard, now = 1, 7.0, 7.5
    p0, v0 = _state(circle8, heard)
    track, _ = follow(p0[lost_index], v0[lost_index], p0[lost_index], v0[lost_index],
                      round(5.0 / STEP_S))
    from_now = round((now - heard) / STEP_S)
    lost = track[from_now:from_now + round(2.5 / STEP_S) + 1]

    def predicted(s: np.ndarray) -> np.ndarray:
        index = np.minimum(np.round(s / STEP_S).astype(int), lost.shape[0] - 1)
        at: np.ndarray = lost[index]
        return at

    p, v = _state(circle8, now)
    held = [i for i in range(8) if i != lost_index]
    ids = [circle8.scenario.ids[i] for i in held]
    hold = silent_hold(circle8, predicted, now, ids, p[held], v[held], RATE)
    assert abs(hold - now) <= HOLD_WINDOW_S + 1e-9
    assert round(hold * RATE) == pytest.approx(hold * RATE)  # on the stream's grid
    here = _room(circle8, lost, held, p, v, now)
    chosen = _room(circle8, lost, held, p, v, hold)
    assert here < 0.9
    assert chosen >= 0.98 and chosen > here


def test_a_silent_vehicle_far_from_everyone_holds_the_fleet_where_it_is(
        circle8: planner.Plan) -> None:
    """Nobody within reach of the silent one's motion: the hold is the plan time reached."""
    now = 5.0
    p, v = _state(circle8, now)
    far = np.array([60.0, 60.0, 2.0])
    hold = silent_hold(circle8, lambda s: np.repeat(far[None], len(s), axis=0), now,
                       list(circle8.scenario.ids[1:]), p[1:], v[1:], RATE)
    assert hold == pytest.approx(now)


@pytest.mark.parametrize("shift", [-7, 4])
def test_a_pause_holding_another_plan_tick_resumes_from_it(shift: int) -> None:
    """A pause may hold a plan tick before or after the one reached: the flight time while
    paused is the one held, and after the resume it runs on from there."""
    clock = FlightClock(rate=10.0, epoch=0.0, t0=0.0)
    clock.begin(20)
    pause = clock.stop(50, 30 + shift)
    assert pause.plan_tick == 30 + shift and pause.shift == pytest.approx(shift / 10)
    assert clock.flight_time() == pytest.approx((30 + shift) / 10)
    clock.restart(80)
    assert 80 - clock.start_tick == 30 + shift  # the next tick flies plan tick 30 + shift
    # flight time on the GCS clock agrees with the tick count: 8.0 s is streamer tick 80
    assert clock.start is not None
    assert 8.0 - clock.start - clock.paused_total == pytest.approx((30 + shift) / 10)
