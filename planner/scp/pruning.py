"""Where an SCP iteration looks for separation rows: the rows it starts with, and the rows
that can be broken after a solve.

`seed_keys` gives the rows an iteration starts with (the deepest point of every close
approach at the linearisation point). `margins` bounds, per pair and interval, how far every
row holds at the linearisation point; a row set can be broken only once its two vehicles
have moved more than that in total (`suspects`), so the all-pairs check after each solve
(`broken_rows`) computes row values only there. Large fleets get exact margins only where
a broad phase finds a pair near (`planner.scp.separation.near_windows`), a lower bound elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.model.scenario import Scenario
from planner.scp.group_solver import Codec, Keys, Trajectories, starts_moving
from planner.scp.separation import (
    CHUNK,
    NEAR_MIN_VEHICLES,
    PairSteps,
    all_pairs,
    close_among,
    close_rows,
    far_margin_bound,
    interval_margins,
    near_windows,
    pair_index,
    row_displacements,
    values_among,
    violated_among,
    window_rows,
    worst_per_run,
)
from planner.types import FloatArray, IntArray

if TYPE_CHECKING:
    from planner.options import ScpOptions

__all__ = ["FAR_SLACK", "MARGIN_WINDOW", "Pruning", "broken_rows", "margins", "seed_keys",
           "suspects"]

#: The broad phase's reach beyond R and the vehicles' own step terms, in units of R (see
#: `margins`).
FAR_SLACK = 1.0
#: Steps per time window of the margins' broad phase (`margins`): exact margins are
#: computed only in the windows where a pair is near.
MARGIN_WINDOW = 4


def _expand(pairs: PairSteps, last: int) -> PairSteps:
    """Pair-steps plus their neighbours k-1 and k+1 (within 0..last)."""
    parts = []
    for shift in (-1, 0, 1):
        k = pairs.k + shift
        ok = (k >= 0) & (k <= last)
        parts.append(PairSteps(pairs.i[ok], pairs.j[ok], k[ok]))
    return PairSteps.concat(parts)


def seed_keys(lin: Trajectories, scenario: Scenario, options: ScpOptions,
              codec: Codec) -> Keys:
    """Rows an iteration starts with (besides those carried over as active): the deepest
    point of every close approach and its neighbours; every row with culling off."""
    lin_positions = lin[0]
    n, stages = lin_positions.shape[0], lin_positions.shape[1]
    count = stages - 1 if options.continuous else stages
    if not options.culling:
        i, j = all_pairs(n)
        k = np.tile(np.arange(count, dtype=np.intp), len(i))
        return codec.encode(PairSteps(np.repeat(i, count), np.repeat(j, count), k))
    below = scenario.min_separation * (1.0 + options.candidate_margin)
    if n >= NEAR_MIN_VEHICLES:  # only the intervals of the windows where a pair is near
        near = near_windows(*lin, scenario.dt, scenario.separation_scale, below, MARGIN_WINDOW)
        pairs, distance = close_among(
            lin_positions, scenario.separation_scale, below, options.continuous,
            window_rows(near, MARGIN_WINDOW, options.continuous, stages - 1))
    else:
        pairs, distance = close_rows(lin_positions, scenario.separation_scale, below,
                                     options.continuous)
    return np.unique(codec.encode(_expand(worst_per_run(pairs, distance), count - 1)))


@dataclass(frozen=True)
class Pruning:
    """What the all-pairs row check knows at `lin` (see `margins`): a row set can be broken
    only where its value at `lin` exceeds R by less than its two vehicles have moved."""

    near_i: IntArray
    near_j: IntArray
    near: FloatArray
    """(near pairs, K or K+1): each interval's (step's) smallest row value at `lin` - R
    (or (near pairs, 1): one bound for all of a pair's intervals)."""
    far: FloatArray | None
    """Per pair (all_pairs order), a lower bound on its smallest row value at `lin` - R,
    +inf for the near pairs; None when every pair is near."""


def margins(scenario: Scenario, options: ScpOptions, lin: Trajectories) -> Pruning:
    """Exact interval margins for every pair in small fleets; in large ones, for the pairs
    and time windows the broad phase finds near, and `far_margin_bound` elsewhere."""
    n, scale, separation = len(lin[0]), scenario.separation_scale, scenario.min_separation
    pair_i, pair_j = all_pairs(n)
    if n < NEAR_MIN_VEHICLES:
        return Pruning(pair_i, pair_j, interval_margins(
            lin[0], lin[1], scenario.dt, scale, options.continuous, separation,
            moving=starts_moving(scenario)) - separation, None)
    half_speed, step = far_margin_bound(lin[0], lin[1], scenario.dt, scale)
    own = half_speed + step
    # Far pairs get a margin of at least FAR_SLACK * R: they are checked only once their
    # vehicles have moved that far from `lin` in total.
    reach = separation * (1.0 + FAR_SLACK) + 2.0 * float(own.max())
    near = near_windows(*lin, scenario.dt, scale, reach, MARGIN_WINDOW)
    keys = np.unique(near.i.astype(np.int64) * n + near.j)
    near_i, near_j = (keys // n).astype(np.intp), (keys % n).astype(np.intp)
    far = reach - separation - own[pair_i] - own[pair_j]
    far[pair_index(near_i, near_j, n)] = np.inf
    # A near pair's intervals outside its near windows keep the far bound.
    count = lin[0].shape[1] - 1 if options.continuous else lin[0].shape[1]
    margin = np.repeat((reach - separation - own[near_i] - own[near_j])[:, None], count, axis=1)
    rows = window_rows(near, MARGIN_WINDOW, options.continuous, lin[0].shape[1] - 1)
    at = np.searchsorted(keys, rows.i.astype(np.int64) * n + rows.j)
    margin[at, rows.k] = values_among(
        lin[0], lin[0], lin[1], scenario.dt, scale, separation, options.continuous, rows,
        starts_moving(scenario)) - separation
    return Pruning(near_i, near_j, margin, far)


def suspects(pruning: Pruning, moved: FloatArray, tolerance: float) -> PairSteps:
    """The near pairs' intervals (steps) that may be broken after the vehicles moved by
    `moved` (`row_displacements`) from `lin`, in pair chunks that bound memory."""
    per = max(1, CHUNK // moved.shape[1])
    parts = []
    for lo in range(0, len(pruning.near_i), per):
        i, j = pruning.near_i[lo:lo + per], pruning.near_j[lo:lo + per]
        pi, kk = np.nonzero(pruning.near[lo:lo + per] - moved[i] - moved[j] < tolerance)
        parts.append(PairSteps(i[pi], j[pi], kk.astype(np.intp)))
    return PairSteps.concat(parts)


def broken_rows(scenario: Scenario, options: ScpOptions, pruning: Pruning, lin: Trajectories,
                current: tuple[FloatArray, FloatArray]) -> PairSteps:
    """The pair-steps whose rows (linearised about `lin`) the positions and velocities
    `current` break by more than the violation tolerance, checked only where `pruning`
    says they can be."""
    p, v = current
    tolerance, scale = options.violation_tolerance, scenario.separation_scale
    moved = row_displacements(lin[:2], current, scenario.dt, scale, options.continuous)
    violated, _ = violated_among(
        lin[0], p, v, scenario.dt, scale, scenario.min_separation, tolerance,
        options.continuous, suspects(pruning, moved, tolerance), starts_moving(scenario),
    )
    if pruning.far is not None:
        pair_i, pair_j = all_pairs(len(p))
        most = moved.max(axis=1)
        far = np.flatnonzero(pruning.far - most[pair_i] - most[pair_j] < tolerance)
        if far.size:  # pairs the broad phase left out, whose vehicles moved far
            beyond, _ = violated_among(
                lin[0], p, v, scenario.dt, scale, scenario.min_separation, tolerance,
                options.continuous, suspects(Pruning(
                    pair_i[far], pair_j[far], pruning.far[far, None], None), moved,
                    tolerance), starts_moving(scenario),
            )
            violated = PairSteps.concat([violated, beyond])
    return violated
