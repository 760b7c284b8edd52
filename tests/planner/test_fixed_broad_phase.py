"""The fixed-trajectory broad phase (`planner.scp.fixed_rows.FixedRows.near`) compares boxes over
blocks of steps before single intervals: it must find exactly the triples that the
interval-by-interval comparison finds (never drop one within reach), and small groups' QPs
share their equality and cost matrices (`planner.scp.qp.group_structure`) without changing them."""

from __future__ import annotations

import numpy as np
import pytest

from planner.families.generators import grid_to_sphere
from planner.model.fixed import FixedSet
from planner.model.scenario import Scenario
from planner.scp import qp
from planner.scp.fixed_rows import BLOCK, FixedRows, interval_boxes
from planner.scp.qp import SeparationRows, build_group_qp


def _scenario(steps: int) -> Scenario:
    return Scenario.from_dict(grid_to_sphere(8, seed=0, steps=steps)).assigned()


def _walks(rng: np.random.Generator, count: int, stages: int) -> tuple[np.ndarray, np.ndarray]:
    p = np.cumsum(rng.normal(0.0, 0.4, (count, stages, 3)), axis=1) \
        + rng.uniform(-5.0, 5.0, (count, 1, 3))
    return p, rng.normal(0.0, 1.0, (count, stages, 3))


def _rows(scenario: Scenario, rng: np.random.Generator, count: int) -> FixedRows:
    p, v = _walks(rng, count, scenario.steps + 1)
    fs = FixedSet([f"f{i}" for i in range(count)], p, v, np.zeros((count, scenario.steps, 3)),
                  np.full(count, 0.3), rng.uniform(0.0, 0.3, (count, scenario.steps)))
    return FixedRows(scenario.with_fixed_set(fs))


def _every_interval(rows: FixedRows, p: np.ndarray, v: np.ndarray, reach: float) -> set:
    """The triples whose interval boxes come within R + margin + reach, one by one."""
    lo, hi = interval_boxes(p, v, rows.dt, rows.scale)
    fixed = rows.fixed_set
    f_lo, f_hi = interval_boxes(fixed.positions, fixed.velocities, rows.dt, rows.scale)
    gap = np.maximum(0.0, np.maximum(lo[:, None] - f_hi[None], f_lo[None] - hi[:, None]))
    close = (gap ** 2).sum(axis=-1) <= (rows.separation + rows.margins + reach)[None] ** 2
    return set(zip(*(x.tolist() for x in np.nonzero(close)), strict=True))


# 150 steps: whole blocks; 147: a last block shorter than BLOCK
@pytest.mark.parametrize("steps", [150, 147])
def test_the_blocked_broad_phase_finds_every_triple_the_interval_test_finds(steps: int) -> None:
    assert steps % BLOCK in (0, 7)
    scenario = _scenario(steps)
    rng = np.random.default_rng(3)
    for _ in range(3):
        rows = _rows(scenario, rng, 23)
        p, v = _walks(rng, 4, steps + 1)
        for reach in (0.0, 0.3, 2.0):
            found = rows.near(p, v, reach)
            got = set(zip(found.vehicle.tolist(), found.fixed.tolist(), found.k.tolist(),
                          strict=True))
            want = _every_interval(rows, p, v, reach)
            assert want, "the walks should meet"
            assert got == want


def test_small_groups_share_their_equality_and_cost_matrices_unchanged() -> None:
    scenario = Scenario.from_dict(grid_to_sphere(8, seed=0)).assigned()
    one = build_group_qp(scenario, np.array([0, 1]), SeparationRows.empty())
    two = build_group_qp(scenario, np.array([5, 3]), SeparationRows.empty())
    assert one.A is two.A and one.P is two.P
    fresh_a, fresh_p = qp.build_structure(scenario.steps, 2, scenario.dt)
    assert abs(one.A - fresh_a).max() == 0 and abs(one.P - fresh_p).max() == 0
    # the boundary conditions are the members' own
    assert not np.array_equal(one.b, two.b)
    large = qp.STRUCTURE_CACHE_VEHICLES + 1
    members = np.arange(large) % len(scenario.vehicles)
    assert build_group_qp(scenario, members, SeparationRows.empty()).A \
        is not build_group_qp(scenario, members, SeparationRows.empty()).A
