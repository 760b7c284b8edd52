"""Prioritized batches on crowds crossing a centre (grid -> sphere with fixed goals): a
vehicle at a time by default, every vehicle keeping R from the earlier ones over continuous
time, and the first guesses' blocked gap test (`planner.methods.first_guess.Placed`) agreeing with
the step-by-step distances."""

from __future__ import annotations

import dataclasses

import numpy as np

import planner.methods.first_guess as first_guess
import planner.methods.prioritized as prioritized
from planner import plan
from planner.families.generators import grid_to_sphere, sideways
from planner.families.obstacle_generators import forest
from planner.model.scenario import Scenario
from planner.scp.loop import DEFAULT_BATCH
from planner.scp.solvers import make_solver
from planner.verification.verify import verify
from tests.planner.batches_support import assert_each_batch_clear


def _crowd(vehicles: int = 24) -> Scenario:
    return Scenario.from_dict(grid_to_sphere(vehicles, seed=0)).assigned()


def test_a_crowd_goes_a_vehicle_at_a_time_a_fleet_moving_as_one_in_pairs() -> None:
    assert prioritized.batch_size(_crowd()) == 1
    assert prioritized.batch_size(Scenario.from_dict(sideways(16)).assigned()) == DEFAULT_BATCH
    # a crowd among obstacles stays in pairs (measured no faster alone)
    woods = Scenario.from_dict(forest(8, 6, size=20.0, seed=0)).assigned()
    assert prioritized.dominant_motion(woods) is None and woods.obstacles
    assert prioritized.batch_size(woods) == DEFAULT_BATCH
    assert prioritized.batch_size(_crowd(), 3) == 3  # asked for: as asked


def test_a_crowd_plans_one_vehicle_per_batch_each_clear_of_the_earlier_ones() -> None:
    work = _crowd()
    found = prioritized.plan_batches(work, make_solver(None))
    assert_each_batch_clear(work, found)
    assert isinstance(found, prioritized.PrioritizedOutcome)
    assert [len(b) for b in found.batches] == [1] * len(work.vehicles)
    straight = verify(work, *_straight(work))
    assert not straight.separated  # the crowd does meet


def _straight(work: Scenario) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from planner.scp.first_qp import straight_moves
    return straight_moves(work)


def test_plan_with_default_batches_on_a_crowd_is_converged_and_verified() -> None:
    result = plan(grid_to_sphere(24, seed=1), method="prioritized")
    assert result.status == "converged", result.message
    assert result.verification is not None and result.verification.verified
    assert result.verification.min_separation_continuous >= 1.0 - 1e-4
    assert "batches of up to 1 vehicles" in result.message


def test_the_blocked_gaps_are_the_step_distances_where_they_matter() -> None:
    rng = np.random.default_rng(7)
    stages = 151
    def walks(count: int) -> np.ndarray:
        return (np.cumsum(rng.normal(0.0, 0.3, (count, stages, 3)), axis=1)
                + rng.uniform(-12.0, 12.0, (count, 1, 3)))

    placed_points = walks(12)
    placed = first_guess.Placed(placed_points)
    trial = walks(40)
    exact = np.linalg.norm(trial[:, None] - placed_points[None], axis=3).min(axis=(1, 2))
    for need in np.quantile(exact, [0.2, 0.5, 0.8]):  # some candidates fail, some clear
        gaps = placed.gaps(trial, need)
        near = exact < need
        assert near.any() and (~near).any(), need  # both kinds of candidate
        assert np.allclose(gaps[near], exact[near])  # exact wherever the candidate fails
        assert (gaps[~near] >= need).all()  # and at least `need` wherever it is clear
    # a trajectory added later is compared too
    placed.add(trial[0])
    assert placed.gaps(trial[:1], 1.0)[0] == 0.0


def _reference_guess(scenario: Scenario, others: np.ndarray, crossing: bool) -> np.ndarray:
    """clear_guess's choice computed the plain way: every candidate against every placed
    trajectory at every step, try by try (the straight move, then each delay)."""
    from planner.methods.routes import along
    scale = scenario.separation_scale
    need = first_guess.GUESS_GAP * scenario.min_separation
    placed = [others / scale]
    out = []
    for i in range(len(scenario.vehicles)):
        lines = first_guess.polylines(scenario, i)
        wide = first_guess.polylines(scenario, i, wide=True)
        assert np.array_equal(wide[:len(lines)], lines)  # the wide set extends the first
        against = np.concatenate(placed)
        chosen, best = (lines[0], 0), -np.inf
        steps = scenario.steps
        first = [(lines[:1], 0)] + [(lines, int(d * steps)) for d in first_guess.DELAYS]
        then = ([(wide[len(lines):], int(d * steps)) for d in first_guess.DELAYS]
                + [(wide, int(d * steps)) for d in first_guess.WIDE_DELAYS])
        for number, (subset, delay) in enumerate(first + then):
            if number == len(first) and (not crossing or best >= scenario.min_separation):
                break  # the wide candidates: in a crowd crossing a point, less than R kept
            trial = first_guess.positions_along(subset, scenario, delay) / scale
            gap = np.linalg.norm(trial[:, None] - against[None], axis=3).min(axis=(1, 2))
            clear = np.flatnonzero(gap >= need)
            pick = int(clear[0]) if clear.size else int(np.argmax(gap))
            if clear.size or gap[pick] > best:
                chosen, best = (subset[pick], delay), float(gap[pick])
            if clear.size:
                break
        p = along(chosen[0], scenario, chosen[1])[0]
        out.append(p)
        placed.append(p[None] / scale)
    return np.stack(out)


def test_the_first_guess_is_the_plain_try_by_try_choice() -> None:
    from planner.scp.first_qp import straight_moves
    work = _crowd(64)
    straight = straight_moves(work)[0]
    rng = np.random.default_rng(2)
    order = rng.permutation(len(work.vehicles))
    waited = 0
    for split in (8, 30, 56):
        mine = order[split:split + 4]
        sub = dataclasses.replace(work, vehicles=tuple(work.vehicles[j] for j in mine),
                                  starts=work.starts[mine], goals=work.goals[mine])
        for crossing in (False, True):
            guess = first_guess.clear_guess(sub, straight[order[:split]], crossing=crossing)[0]
            np.testing.assert_array_equal(
                guess, _reference_guess(sub, straight[order[:split]], crossing))
        waited += int((np.linalg.norm(guess[:, 1] - sub.starts, axis=1) < 1e-12).sum())
    assert waited > 0  # some vehicle had to wait: the delayed candidates were exercised


def test_a_crowd_crossing_one_point_is_told_from_one_that_does_not() -> None:
    from planner.families.generators import antipodal_circle, antipodal_sphere, facing_grids
    crossing = [antipodal_sphere(40), antipodal_circle(20), facing_grids(40)]
    other = [facing_grids(40, pairing="across"), grid_to_sphere(64, seed=0)]
    for data in crossing + other:
        assert first_guess.crosses_one_point(Scenario.from_dict(data)) == (data in crossing)


def test_an_antipodal_crowd_plans_in_batches_none_replanned_with_earlier_vehicles() -> None:
    from planner.families.generators import antipodal_sphere
    result = plan(antipodal_sphere(32), method="prioritized")
    assert result.status == "converged" and result.verification.verified
    assert result.message.startswith("planned in 32 prioritized batches")
    assert "replanned with earlier vehicles" not in result.message
