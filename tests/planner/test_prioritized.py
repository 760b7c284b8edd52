"""Prioritized batches (`planner.methods.prioritized`, method "prioritized"): the joined plan is
verified as a whole, each batch keeps R from the earlier ones over continuous time, and a batch
that fails is replanned with earlier vehicles or the fleet planned whole."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

import planner.methods.prioritized as prioritized
import planner.methods.stages as stages
from planner import Plan, plan
from planner.errors import ScenarioError
from planner.families.generators import circle_swap, sideways
from planner.model.fixed import FixedTrajectory, landing_motion
from planner.model.from_state import scenario_from_state
from planner.model.scenario import Scenario
from planner.options import PlanningOptions
from planner.scp.loop import ScpOutcome
from planner.scp.solvers import make_solver
from planner.verification.verify import verify
from tests.planner.batches_support import assert_each_batch_clear, flying_swap

PRIORITIZED = PlanningOptions(batch_size=2)


def _batched(data: Any, options: PlanningOptions = PRIORITIZED) -> Plan:
    """`data` planned with method prioritized."""
    return plan(data, options=options, method="prioritized")


def _outcomes(result: Plan) -> dict[str, str]:
    """Each method's outcome in the plan's attempts."""
    return {a.method: a.outcome for a in result.attempts}


def _reason(result: Plan, method: str) -> str:
    return next(a.reason for a in result.attempts if a.method == method)


def _small_sideways() -> Scenario:
    return Scenario.from_dict(sideways(16)).assigned()


def test_a_decomposed_plan_is_converged_verified_and_says_how_it_was_planned() -> None:
    result = _batched(sideways(16))
    assert result.status == "converged", result.message
    assert result.verification is not None and result.verification.verified
    assert result.verification.min_separation_continuous >= 1.0 - 1e-4
    assert "prioritized batches" in result.message
    assert result.method == "prioritized" and _outcomes(result)["prioritized"] == "won"
    assert all(r.method == "prioritized" for r in result.iterations)
    whole = plan(sideways(16), method="whole")
    assert whole.method == "whole" and "prioritized" not in _outcomes(whole)


def test_each_batch_keeps_r_from_the_earlier_batches_over_continuous_time() -> None:
    work = _small_sideways()
    found = prioritized.plan_batches(work, make_solver(None), batch=2)
    assert_each_batch_clear(work, found)
    # and the batches did meet: without the earlier ones the straight moves would collide
    straight = verify(work, *_straight(work))
    assert not straight.separated


def _straight(work: Scenario) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from planner.scp.first_qp import straight_moves
    return straight_moves(work)


def test_the_order_sweeps_along_the_motion_far_goals_first() -> None:
    work = _small_sideways()
    order = prioritized.order_vehicles(work)
    motion = (work.goals - work.starts).mean(axis=0)
    assert motion[0] > 0.9 * np.linalg.norm(motion)  # sideways: mostly along +x
    along = work.goals[order] @ motion
    assert (np.diff(along) <= 1e-9).all()
    swap = Scenario.from_dict(circle_swap(6))  # no dominant motion: longest moves first
    lengths = np.linalg.norm(swap.goals - swap.starts, axis=1)[prioritized.order_vehicles(swap)]
    assert (np.diff(lengths) <= 1e-9).all()


def test_a_failed_batch_is_replanned_with_the_earlier_vehicles_nearest_to_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    work = _small_sideways()
    real = prioritized.run_scp
    seen: list[tuple[str, int]] = []

    def first_try_of_batch_3_fails(sub: Scenario, *args: Any, **kwargs: Any) -> ScpOutcome:
        seen.append((sub.name, len(sub.vehicles)))
        out = real(sub, *args, **kwargs)
        if sub.name.endswith("#batch3"):
            return dataclasses.replace(out, status="infeasible")
        return out

    monkeypatch.setattr(prioritized, "run_scp", first_try_of_batch_3_fails)
    found = prioritized.plan_batches(work, make_solver(None), batch=2)
    assert isinstance(found, prioritized.PrioritizedOutcome), found
    names = dict(seen)
    assert names[f"{work.name}#batch3"] == 2
    assert names[f"{work.name}#batch3+"] == 2 + prioritized.MERGE_GROWTH
    assert "replanned with earlier vehicles" in found.outcome.message
    out = found.outcome
    assert verify(work, out.positions, out.velocities, out.accelerations).verified


def test_a_batch_that_fails_again_after_its_deferral_ends_the_decomposition() -> None:
    # a tube too narrow to pass in, and the two swap ends: whichever is planned first has
    # to fly through the other's reserved start, deferred or not
    tube = {"name": "tube", "dt": 0.2, "steps": 60, "min_separation": 1.0,
            "limits": {"position_min": [0, 0, 0], "position_max": [10, 0.6, 0.6],
                       "velocity_max": [3, 3, 3], "acceleration_max": [3, 3, 3]},
            "vehicles": [{"id": "a", "start": [1, 0.3, 0.3], "goal": [8, 0.3, 0.3]},
                         {"id": "b", "start": [8.5, 0.3, 0.3], "goal": [2, 0.3, 0.3]}]}
    work = Scenario.from_dict(tube)
    assert prioritized.plan_batches(work, make_solver(None), batch=1,
                                    order=np.array([0, 1])) == prioritized.NOT_CONVERGED


def test_plan_falls_back_to_the_whole_fleet_when_the_batches_fail(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(stages, "plan_batches",
                        lambda *args, **kwargs: prioritized.NOT_CONVERGED)
    result = _batched(sideways(16))
    assert result.status == "converged", result.message
    assert result.verification is not None and result.verification.verified
    assert result.method == "whole"
    assert _outcomes(result) == {"separated_first": "declined", "prioritized": "failed",
                                 "dodge": "declined", "whole": "won"}
    assert _reason(result, "prioritized") == prioritized.NOT_CONVERGED


@pytest.mark.parametrize("value", [0, 2.5])
def test_bad_batch_sizes_are_refused_naming_the_field(value: Any) -> None:
    with pytest.raises(ValueError, match=r"^batch_size: "):
        PlanningOptions(batch_size=value)


def test_an_unknown_method_is_refused_naming_the_field() -> None:
    with pytest.raises(ScenarioError) as caught:
        plan(sideways(4), method="greedy")
    assert caught.value.field == "method" and "'auto', 'whole', 'prioritized'" in str(caught.value)


def test_a_joined_plan_that_fails_verification_is_never_returned(
        monkeypatch: pytest.MonkeyPatch) -> None:
    def colliding(work: Scenario, *args: Any, **kwargs: Any) -> prioritized.PrioritizedOutcome:
        p, v, a = _straight(work)  # the crowd's straight moves: vehicles meet
        joined = ScpOutcome("converged", "planned in 1 prioritized batches", p, v, a, [], 0.0)
        return prioritized.PrioritizedOutcome(joined, [np.arange(len(p))], [0.0])

    monkeypatch.setattr(stages, "plan_batches", colliding)
    result = _batched(sideways(16))
    assert result.status == "converged", result.message
    assert result.verification is not None and result.verification.verified
    assert result.method == "whole" and _outcomes(result)["prioritized"] == "failed"
    assert _reason(result, "prioritized").startswith("the joined batches failed verification")


def _from_state(t: float, margin: float) -> tuple[Scenario, FixedTrajectory]:
    """The swap replanned from its state at t to its goals, with a vehicle dropped (not
    planned) on its way down through the middle of the square, keeping R + `margin`."""
    base, p, v, a = flying_swap(t)
    dropped = landing_motion("x", [5.0, 5.0, 2.9], [0.0, 0.0, 0.0], base.dt, 2.0, 0.5, 0.3,
                             margin=margin)
    work = scenario_from_state(base, "replan", base.ids, p, v, a, base.goals,
                               separation=base.min_separation, steps=base.steps,
                               fixed=[dropped])
    return work, dropped


def test_batches_from_a_moving_state_start_exactly_there_and_keep_r_from_a_fixed_vehicle(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """From a flying state the batches plan every vehicle from its exact position, velocity
    and acceleration, keep R from each other and R + margin from the scenario's own fixed
    vehicle over continuous time (every batch has it), reserve no later vehicle (a moving
    vehicle cannot wait where it is) and stop at their share of the threshold."""
    work, dropped = _from_state(2.0, 0.2)
    assert np.abs(work.start_velocities).max() > 0.5  # truly in motion
    real = prioritized.run_scp
    subs: list[Scenario] = []

    def spy(sub: Scenario, *args: Any, **kwargs: Any) -> ScpOutcome:
        subs.append(sub)
        return real(sub, *args, **kwargs)

    monkeypatch.setattr(prioritized, "run_scp", spy)
    found = prioritized.plan_batches(work, make_solver(None), batch=2, cost_share=True)
    assert isinstance(found, prioritized.PrioritizedOutcome), found
    out = found.outcome
    np.testing.assert_allclose(out.positions[:, 0], work.starts, atol=1e-6)
    np.testing.assert_allclose(out.velocities[:, 0], work.start_velocities, atol=1e-6)
    check = verify(work, out.positions, out.velocities, out.accelerations)
    assert check.verified, check.failures()
    assert check.fixed_distance_min >= work.min_separation + 0.2 - 1e-4
    planned_before: set[str] = set()
    for sub in subs:
        ids = [f.id for f in sub.fixed]
        assert ids[0] == "x"  # the dropped vehicle, in every batch
        assert {i[1:] for i in ids[1:]} <= planned_before  # earlier vehicles only
        assert sub.cost_threshold == pytest.approx(
            work.cost_threshold * len(sub.vehicles) / len(work.vehicles))
        planned_before |= {v.id for v in sub.vehicles}
    # the fixed vehicle mattered: the separation-free moves fly through its column
    free = verify(dataclasses.replace(work, fixed=(dropped,)), *_straight(work))
    assert free.fixed_distance_min < work.min_separation


def test_plan_decomposes_a_moving_fleet_and_verifies_the_joined_plan() -> None:
    work, _ = _from_state(3.0, 0.0)
    result = _batched(work)
    assert result.status == "converged", result.message
    assert result.method == "prioritized"
    assert result.verification is not None and result.verification.verified
    np.testing.assert_allclose(result.positions()[:, 0], work.starts, atol=1e-6)
    np.testing.assert_allclose(result.velocities()[:, 0], work.start_velocities, atol=1e-6)


def test_batches_costing_more_than_the_threshold_above_the_free_optimum_are_not_taken() -> None:
    """With `batch_cost_share` the joined plan is taken only within `cost_threshold` of the
    separation-free optimum (so of the fleet's optimum): above it, the fleet is planned
    whole, saying why."""
    work, _ = _from_state(2.0, 0.2)  # the free moves cross the dropped vehicle's column
    options = dataclasses.replace(PRIORITIZED, batch_cost_share=True)
    loose = _batched(dataclasses.replace(work, cost_threshold=1e3), options)
    assert loose.ok and loose.method == "prioritized"
    tight = _batched(dataclasses.replace(work, cost_threshold=1e-3), options)
    assert tight.ok, tight.message
    assert tight.method == "whole" and _outcomes(tight)["prioritized"] == "failed"
    assert "above the separation-free optimum, not less than cost_threshold" in _reason(
        tight, "prioritized")


def _corridor() -> dict[str, Any]:
    """Two vehicles in a corridor too narrow to pass in: `back` flies through the start of
    `front`, which moves on ahead of it."""
    return {"name": "corridor", "dt": 0.2, "steps": 60, "min_separation": 1.0,
            "limits": {"position_min": [0.0, 0.0, 0.5], "position_max": [16.0, 1.2, 1.7],
                       "velocity_max": [2.0, 2.0, 2.0], "acceleration_max": [3.0, 3.0, 3.0],
                       "jerk_max": [5.0, 5.0, 5.0]},
            "vehicles": [{"id": "back", "start": [1.0, 0.6, 1.1], "goal": [10.0, 0.6, 1.1]},
                         {"id": "front", "start": [4.0, 0.6, 1.1],
                          "goal": [14.0, 0.6, 1.1]}]}


def test_a_batch_blocked_by_a_later_vehicles_start_is_deferred_until_it_has_left() -> None:
    work = Scenario.from_dict(_corridor()).assigned()
    # `back` first: `front` waits at its start, in the way, so `back`'s batch cannot plan
    found = prioritized.plan_batches(work, make_solver(None), batch=1,
                                     order=np.array([0, 1], dtype=np.intp))
    assert isinstance(found, prioritized.PrioritizedOutcome), found
    assert [b.tolist() for b in found.batches] == [[1], [0]]
    assert "1 deferred to the end of the order" in found.outcome.message
    out = found.outcome
    check = verify(work, out.positions, out.velocities, out.accelerations)
    assert check.verified, check.failures()
    # `front` is out of the way before `back` passes its start
    assert np.all(out.positions[1, :, 0] >= out.positions[0, :, 0] + 1.0 - 1e-6)
