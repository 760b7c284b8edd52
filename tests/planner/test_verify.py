"""Verification is computed from the trajectories alone and catches what the steps hide."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import planner
from planner.model.dynamics import integrate
from planner.types import FloatArray
from planner.verification.verify import verify
from tests.planner.conftest import load_example


def _two_vehicle_scenario(**changes):
    data = load_example("paper-circle2")
    data.update(changes)
    return planner.Scenario.from_dict(data)


def test_a_crossing_between_steps_is_found():
    scenario = _two_vehicle_scenario(steps=4, dt=1.0)
    # Two vehicles crossing at 2 m/s through the same point exactly between steps 1 and 2:
    # at the steps they are 2 m apart, in between they touch.
    p = np.zeros((2, 5, 3))
    v = np.zeros((2, 5, 3))
    a = np.zeros((2, 4, 3))
    t = np.arange(5.0)
    p[0, :, 0] = 1.0 + 2.0 * (t - 1.5)
    p[1, :, 0] = 1.0 - 2.0 * (t - 1.5)
    p[:, :, 1:] = [2.5, 1.5]
    v[0, :, 0], v[1, :, 0] = 2.0, -2.0
    check = verify(scenario, p, v, a)
    assert check.min_separation == 2.0
    assert check.min_separation_continuous < 1e-9
    assert abs(check.closest_time - 1.5) < 1e-6
    assert not check.separated


def test_continuous_minimum_matches_dense_sampling_on_random_motion():
    scenario = _two_vehicle_scenario(steps=30, dt=0.2)
    rng = np.random.default_rng(4)
    a = rng.normal(scale=2.0, size=(2, 30, 3))
    starts = np.array([[1.0, 1.0, 1.0], [2.0, 1.5, 1.2]])
    p, v = integrate(starts, rng.normal(size=(2, 3)), a, 0.2)
    check = verify(scenario, p, v, a)
    times = np.linspace(0, 6.0, 60001)
    dense = planner.interpolate(p, v, a, 0.2, times).position
    brute = np.linalg.norm(dense[0] - dense[1], axis=-1).min()
    assert abs(check.min_separation_continuous - brute) < 1e-6


def test_position_overshoot_between_steps_is_a_violation():
    scenario = _two_vehicle_scenario(steps=4, dt=1.0)
    top = scenario.limits.position_max[2]
    # At the steps the first vehicle is at the ceiling, but it rises above it in between.
    p = np.array([[[1, 1, top - 0.5], [1, 1, top], [1, 1, top - 0.5], [1, 1, top - 1.0],
                   [1, 1, top - 1.5]], [[4, 4, 1.0]] * 5], dtype=float)
    # z(s) = top - 0.5 + 1.5 s - s^2 peaks at s = 0.75 at top + 0.0625.
    v = np.array([[[0, 0, 1.5]] + [[0, 0, -0.5]] * 4, np.zeros((5, 3))])
    a = np.array([[[0, 0, -2.0]] + [[0, 0, 0.0]] * 3, np.zeros((4, 3))])
    check = verify(scenario, p, v, a)
    assert abs(check.max_violation["position"] - 0.0625) < 1e-12
    assert not check.within_bounds


def test_limits_and_flyability():
    scenario = _two_vehicle_scenario()
    plan = planner.plan(scenario)
    assert plan.verification.flyable
    tight = dataclasses.replace(scenario.limits, thrust_max=9.81 + 1e-9, body_rate_max=1e-6)
    check = verify(dataclasses.replace(scenario, limits=tight), plan.positions(),
                   plan.velocities(), plan.accelerations())
    assert not check.flyable
    assert check.thrust_range[1] > 9.81


def _hovering_pair(gap: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Two vehicles hovering `gap` m apart along x for 4 steps of 1 s."""
    p = np.zeros((2, 5, 3))
    p[0, :] = [2.0, 2.5, 1.5]
    p[1, :] = [2.0 + gap, 2.5, 1.5]
    return p, np.zeros((2, 5, 3)), np.zeros((2, 4, 3))


@pytest.mark.parametrize("scale", [1e-300, 5e-324])
def test_an_overflowing_distance_is_not_separated(scale):
    """Scaled by 1e-300, 0.40 m is 4e299 and its square overflows: the distance is
    undefined, and undefined is a failure, never 'separated'."""
    scenario = _two_vehicle_scenario(steps=4, dt=1.0)
    # the scenario parser refuses this scale; the verifier must not depend on that
    tiny = dataclasses.replace(scenario, separation_scale=np.full(3, scale))
    with np.errstate(all="raise"):  # and no floating-point warning escapes
        check = verify(tiny, *_hovering_pair(0.40))
    assert not check.separated and not check.verified
    assert check.min_separation is None and check.min_separation_continuous is None
    assert any("separation" in f and "undefined" in f for f in check.failures())


def test_non_finite_trajectories_fail_every_check():
    scenario = _two_vehicle_scenario(steps=4, dt=1.0)
    p, v, a = _hovering_pair(3.0)
    p[1, 2, 0] = np.nan
    a[0, 1, 2] = np.inf
    check = verify(scenario, p, v, a)
    assert not (check.separated or check.within_bounds or check.flyable)
    assert check.min_separation is None and check.min_separation_continuous is None
    assert len(check.failures()) == 3
    # and the verification block stays valid JSON (no NaN, no Infinity)
    json.dumps(dataclasses.asdict(check), allow_nan=False)


def test_one_vehicle_is_separated_by_definition():
    scenario = planner.Scenario.from_dict(
        load_example("paper-circle2") | {"vehicles": load_example("paper-circle2")["vehicles"][:1]})
    check = verify(scenario, *(x[:1] for x in _hovering_pair(0.0)))
    assert check.separated and check.min_separation is None and check.closest_pair == []


def test_a_widely_spaced_fleet_is_measured_without_all_pairs(monkeypatch):
    """100 vehicles 5 m apart (every pair beyond the broad phase's first reach of 2 R):
    the reach widens instead of checking all pairs over the whole timeline, and the
    minimum is still exact (one vehicle flies towards its neighbour)."""
    from planner.scp import separation
    from planner.verification.verify import continuous_minimum

    def no_all_pairs(*_args):
        raise AssertionError("all pairs examined")

    monkeypatch.setattr(separation, "all_pairs", no_all_pairs)
    x, y = np.meshgrid(np.arange(10) * 5.0, np.arange(10) * 5.0)
    points = np.stack([x.ravel(), y.ravel(), np.full(100, 3.0)], axis=1)
    steps, dt = 6, 0.5
    p = np.repeat(points[:, None, :], steps + 1, axis=1)
    v = np.zeros_like(p)
    a = np.zeros((100, steps, 3))
    # vehicle 0 moves +x towards vehicle 1 (5 m away): it ends 1.5 m on, still moving
    a[0, :, 0] = [1.0, 1.0, -1.0, -1.0, 1.0, 1.0]
    for k in range(steps):
        v[0, k + 1] = v[0, k] + dt * a[0, k]
        p[0, k + 1] = p[0, k] + dt * v[0, k] + 0.5 * dt * dt * a[0, k]
    scenario = dataclasses.replace(_two_vehicle_scenario(), steps=steps, dt=dt)
    step_min, cont_min, i, j, _ = continuous_minimum(scenario, p, v, a)
    # dense sampling of the exact motion of the only pair that comes closer than 5 m
    s = np.linspace(0.0, steps * dt, 2001)
    k = np.minimum((s // dt).astype(int), steps - 1)
    tau = s - k * dt
    x0 = p[0, k, 0] + tau * v[0, k, 0] + 0.5 * tau * tau * a[0, k, 0]
    assert cont_min == pytest.approx(float(np.min(5.0 - x0)), abs=1e-6)
    assert {i, j} == {0, 1} and cont_min < 5.0 - 0.4
    assert step_min == pytest.approx(float(np.min(5.0 - p[0, :, 0])))
