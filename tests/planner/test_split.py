"""Block Gauss-Seidel sweeps for large groups (ScpOptions.split_above): plans stay verified
and close to the whole-group optimum; blocks partition the group."""

from __future__ import annotations

import numpy as np
import pytest

import planner
from planner.families.generators import grid_to_sphere
from planner.scp.group_solver import spatial_blocks
from planner.scp.loop import ScpOptions


def test_spatial_blocks_partition_the_points():
    points = np.random.default_rng(1).random((103, 3)) * [30.0, 5.0, 2.0]
    blocks = spatial_blocks(points, 16)
    assert all(len(b) <= 16 for b in blocks)
    assert sorted(np.concatenate(blocks).tolist()) == list(range(103))
    # Bisection along x (the widest axis): blocks are spatially compact.
    spans = [np.ptp(points[b, 0]) for b in blocks]
    assert max(spans) < 0.5 * np.ptp(points[:, 0])


@pytest.mark.parametrize("seed", [0, 1])
def test_split_groups_give_verified_plans_near_the_whole_group_optimum(seed):
    data = grid_to_sphere(25, seed=seed)
    whole = planner.plan(data, method="whole")
    split = planner.plan(data, options=ScpOptions(split_above=6, block_size=4), method="whole")
    assert whole.ok and split.ok, split.message
    assert split.verification.min_separation_continuous >= 1.0 - 1e-4
    # The sweeps did run (more, smaller QPs) and ended within a hair of the optimum.
    assert (sum(r.qp_solves for r in split.iterations)
            > sum(r.qp_solves for r in whole.iterations))
    assert split.cost == pytest.approx(whole.cost, rel=1e-5)
