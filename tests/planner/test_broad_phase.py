"""The broad phase for large fleets: it only ever leaves out pairs that are provably far, so
plans, row checks and verification come out the same as with every pair examined."""

from __future__ import annotations

import numpy as np
import pytest

import planner
import planner.scp.first_qp
import planner.scp.loop
import planner.scp.pruning
import planner.verification.verify
from planner.families.generators import grid_to_sphere, random_dense
from planner.scp.separation import (
    PairSteps,
    all_pairs,
    far_margin_bound,
    interval_margins,
    interval_minima,
    near_pairs,
    near_windows,
    pair_index,
    pair_margins,
    window_rows,
)
from planner.verification.verify import continuous_minimum


def _wiggly(n: int, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Random but dynamically consistent trajectories (piecewise-constant accelerations)."""
    rng = np.random.default_rng(seed)
    dt = 0.2
    a = rng.normal(scale=2.0, size=(n, steps, 3))
    p = np.empty((n, steps + 1, 3))
    v = np.zeros((n, steps + 1, 3))
    p[:, 0] = rng.random((n, 3)) * [12.0, 12.0, 4.0]
    for k in range(steps):
        p[:, k + 1] = p[:, k] + dt * v[:, k] + 0.5 * dt * dt * a[:, k]
        v[:, k + 1] = v[:, k] + dt * a[:, k]
    return p, v, a, dt


@pytest.mark.parametrize("seed", range(3))
def test_near_pairs_keeps_every_pair_that_comes_close(seed):
    p, v, a, dt = _wiggly(40, 30, seed)
    scale = np.array([1.0, 1.0, 2.0])
    reach = 1.5
    i, j = all_pairs(40)
    k = np.arange(30)
    every = PairSteps(np.repeat(i, 30), np.repeat(j, 30), np.tile(k, len(i)))
    minima, _ = interval_minima(p, v, a, dt, scale, every)
    close = np.unique(pair_index(every.i, every.j, 40)[minima < reach])
    near_i, near_j = near_pairs(p, v, a, dt, scale, reach)
    assert np.all(near_i < near_j)
    found = pair_index(near_i, near_j, 40)
    assert len(close) > 0
    assert np.isin(close, found).all()
    assert len(found) < len(i)  # it did prune


@pytest.mark.parametrize("seed", range(3))
def test_far_pairs_margin_bound_is_below_the_exact_margin(seed):
    p, v, a, dt = _wiggly(40, 30, seed)
    scale = np.ones(3)
    half_speed, step = far_margin_bound(p, v, dt, scale)
    own = half_speed + step
    reach = 2.0 + 2.0 * own.max()
    near_i, near_j = near_pairs(p, v, a, dt, scale, reach)
    i, j = all_pairs(40)
    far = np.ones(len(i), dtype=bool)
    far[pair_index(near_i, near_j, 40)] = False
    exact = pair_margins(p, v, dt, scale, True, 1.0)
    bound = reach - own[i] - own[j]
    assert far.any()
    assert np.all(bound[far] <= exact[far] + 1e-12)


def test_verifier_minimum_is_the_same_with_and_without_the_broad_phase(monkeypatch):
    plan = planner.plan({**grid_to_sphere(64, seed=1), "assignment": "free"})
    scenario = plan.scenario.assigned()
    args = (scenario, plan.positions(), plan.velocities(), plan.accelerations())
    pruned = continuous_minimum(*args)
    monkeypatch.setattr(planner.verification.verify, "NEAR_MIN_VEHICLES", 10**9)
    assert continuous_minimum(*args) == pruned


def test_plans_are_the_same_with_and_without_the_broad_phase(monkeypatch):
    data = random_dense(24, seed=5)
    monkeypatch.setattr(planner.scp.pruning, "NEAR_MIN_VEHICLES", 2)
    monkeypatch.setattr(planner.verification.verify, "NEAR_MIN_VEHICLES", 2)
    # one method: auto's race could pick another winner on a busy machine
    pruned = planner.plan(data, method="whole")
    monkeypatch.setattr(planner.scp.pruning, "NEAR_MIN_VEHICLES", 10**9)
    monkeypatch.setattr(planner.verification.verify, "NEAR_MIN_VEHICLES", 10**9)
    full = planner.plan(data, method="whole")
    assert pruned.ok and full.ok
    assert max(r.separation_rows for r in full.iterations) > 0
    np.testing.assert_allclose(pruned.positions(), full.positions(), atol=1e-7)
    assert (pruned.verification.min_separation_continuous
            == pytest.approx(full.verification.min_separation_continuous, abs=1e-9))


@pytest.mark.parametrize("seed", range(3))
def test_near_windows_keep_every_interval_that_comes_close(seed):
    # Every pair-interval whose continuous-time distance falls below `reach` lies in a
    # (pair, window) the windowed broad phase keeps, and `window_rows` lists it.
    p, v, a, dt = _wiggly(40, 30, seed)
    scale = np.array([1.0, 1.0, 2.0])
    reach, window = 1.5, 4
    i, j = all_pairs(40)
    every = PairSteps(np.repeat(i, 30), np.repeat(j, 30), np.tile(np.arange(30), len(i)))
    minima, _ = interval_minima(p, v, a, dt, scale, every)
    close = every.select(minima < reach).keys(40, 31)
    near = near_windows(p, v, a, dt, scale, reach, window)
    assert np.all(near.i < near.j)
    rows = window_rows(near, window, True, 30)
    assert len(close) > 0
    assert np.isin(close, rows.keys(40, 31)).all()
    assert len(rows) < len(every)  # it did prune
    # The pairs of the windows are what near_pairs finds.
    near_i, near_j = near_pairs(p, v, a, dt, scale, reach, window)
    assert np.array_equal(np.unique(pair_index(near.i, near.j, 40)),
                          pair_index(near_i, near_j, 40))


@pytest.mark.parametrize("continuous", [False, True])
def test_windowed_margins_are_below_the_exact_interval_margins(continuous):
    # The SCP loop's pruning for large fleets: exact margins in the near windows, the far
    # bound elsewhere; never above the exact margin of any interval of any pair.
    scenario = planner.Scenario.from_dict(random_dense(80, seed=2)).assigned()
    lin = planner.scp.first_qp.straight_moves(scenario)
    options = planner.scp.loop.ScpOptions(continuous=continuous)
    pruning = planner.scp.pruning.margins(scenario, options, lin)
    exact = interval_margins(lin[0], lin[1], scenario.dt, scenario.separation_scale,
                             continuous, scenario.min_separation) - scenario.min_separation
    at = pair_index(pruning.near_i, pruning.near_j, 80)
    assert np.all(pruning.near <= exact[at] + 1e-9)
    # Exact where it matters: the pairs closer than R somewhere are near, at those intervals.
    close = exact[at] < 0.0
    assert close.any()
    np.testing.assert_allclose(pruning.near[close], exact[at][close], atol=1e-9)
    assert pruning.far is not None
    far = np.isfinite(pruning.far)
    assert far.any()
    assert np.all(pruning.far[far] <= exact[far].min(axis=1) + 1e-9)
