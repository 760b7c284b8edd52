"""Culling and group splitting do not change the answer: one SCP iteration built with every
pair at every step (one QP for all vehicles) and built lazily (rows only where needed,
independent groups) reach the same optimum within solver tolerance."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import planner
from planner.families.generators import dmpc2019_scenario, random_transitions
from planner.scp.loop import ScpOptions, run_scp
from planner.scp.solvers import make_solver
from tests.planner.conftest import load_example

SCENARIOS = {
    "paper-random4": lambda: load_example("paper-random4"),
    "paper-circle6": lambda: load_example("paper-circle6"),
    "dmpc2019-n6": lambda: dmpc2019_scenario(6, seed=7, trial=3),
    "random10-seed5": lambda: random_transitions(10, size=(6.0, 6.0, 3.0), seed=5, steps=60),
}


def _one_iteration(data, **options):
    scenario = planner.Scenario.from_dict(data)
    scenario = dataclasses.replace(scenario, max_iterations=1)
    return run_scp(scenario, make_solver(), ScpOptions(**options))


@pytest.mark.parametrize("continuous", [False, True], ids=["step-rows", "interval-rows"])
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_culled_equals_all_pairs(name, continuous):
    data = SCENARIOS[name]()
    culled = _one_iteration(data, culling=True, continuous=continuous)
    full = _one_iteration(data, culling=False, continuous=continuous)
    assert culled.status == full.status != "infeasible"
    assert culled.iterations[1].cost == pytest.approx(full.iterations[1].cost, abs=1e-5)
    np.testing.assert_allclose(culled.positions, full.positions, atol=2e-4)
    # Culling really did something: far fewer rows than the all-pairs problem.
    assert culled.iterations[1].separation_rows < full.iterations[1].separation_rows / 3


def test_groups_split_when_vehicles_never_meet():
    data = random_transitions(12, size=(30.0, 30.0, 4.0), seed=3, steps=100)
    plan = planner.plan(data)
    assert plan.ok
    assert max(r.groups for r in plan.iterations[1:]) >= 2


@pytest.mark.parametrize("continuous", [False, True])
def test_pruned_row_check_finds_every_violated_row(continuous):
    from planner.scp.separation import all_pairs, displacements, pair_margins, violated_rows

    data = random_transitions(14, size=(8.0, 8.0, 3.0), seed=11, steps=60)
    scenario = planner.Scenario.from_dict(data)
    lin = planner.plan(scenario)
    rng = np.random.default_rng(0)
    p0, v0 = lin.positions(), lin.velocities()
    for scale_of_move in (0.05, 0.3, 1.0):
        p = p0 + rng.normal(scale=scale_of_move, size=p0.shape)
        v = v0 + rng.normal(scale=scale_of_move, size=v0.shape)
        args = (p0, p, v, scenario.dt, scenario.separation_scale, scenario.min_separation,
                1e-6, continuous)
        everything, _ = violated_rows(*args)
        i, j = all_pairs(14)
        margin = pair_margins(p0, v0, scenario.dt, scenario.separation_scale, continuous,
                              scenario.min_separation)
        moved = displacements((p0, v0), (p, v), scenario.dt, scenario.separation_scale)
        suspect = margin - scenario.min_separation - moved[i] - moved[j] < 1e-6
        pruned, _ = violated_rows(*args, (i[suspect], j[suspect]))
        assert len(everything) > 0
        assert set(zip(everything.i, everything.j, everything.k, strict=True)) == set(
            zip(pruned.i, pruned.j, pruned.k, strict=True))
        if scale_of_move == 0.05:
            assert suspect.sum() < len(i)  # the bound does prune


@pytest.mark.parametrize("continuous", [False, True])
def test_interval_pruned_row_check_finds_every_violated_row(continuous):
    # The per-interval bound of the SCP loop: an interval can be broken only where its
    # margin at lin is below its two vehicles' moves there; checking those intervals alone
    # (violated_among) finds exactly the rows the all-pairs check finds.
    from planner.scp.separation import (
        PairSteps,
        all_pairs,
        interval_margins,
        row_displacements,
        violated_among,
        violated_rows,
    )

    data = random_transitions(14, size=(8.0, 8.0, 3.0), seed=11, steps=60)
    scenario = planner.Scenario.from_dict(data)
    lin = planner.plan(scenario)
    rng = np.random.default_rng(1)
    p0, v0 = lin.positions(), lin.velocities()
    scale, dt, r = scenario.separation_scale, scenario.dt, scenario.min_separation
    i, j = all_pairs(14)
    margin = interval_margins(p0, v0, dt, scale, continuous, r) - r
    for scale_of_move in (0.05, 0.3, 1.0):
        p = p0 + rng.normal(scale=scale_of_move, size=p0.shape)
        v = v0 + rng.normal(scale=scale_of_move, size=v0.shape)
        everything, values = violated_rows(p0, p, v, dt, scale, r, 1e-6, continuous)
        moved = row_displacements((p0, v0), (p, v), dt, scale, continuous)
        pi, kk = np.nonzero(margin - moved[i] - moved[j] < 1e-6)
        suspects = PairSteps(i[pi], j[pi], kk)
        pruned, pruned_values = violated_among(p0, p, v, dt, scale, r, 1e-6, continuous,
                                               suspects)
        assert len(everything) > 0
        key = everything.keys(14, 61)
        assert np.array_equal(np.sort(key), np.sort(pruned.keys(14, 61)))
        np.testing.assert_allclose(pruned_values[np.argsort(pruned.keys(14, 61))],
                                   values[np.argsort(key)], atol=1e-9)
        if scale_of_move == 0.05:
            assert len(suspects) < margin.size / 4  # the bound does prune
