"""Prioritised batches for a crowd: plan a large crowded fleet a batch at a time.

When the separation-free moves of a fixed-goal fleet hold one large crowd, the first SCP
iteration links it into one QP with tens of rows per vehicle, too dense for the dual and
slow as a primal. Here the fleet is split into batches; batch b is planned by the ordinary
SCP loop with every vehicle of batches 0..b-1 held as a fixed trajectory
(`planner.fixed`): its rows to them are one-sided (`planner.one_sided`), bind one vehicle
each and leave the batch's own QP small and dual-friendly. Every batch keeps R from every
earlier one over continuous time by the same rows as any fixed trajectory, so the stitched
plan is separated; `planner.plan` verifies it globally like any plan and falls back to the
whole-fleet SCP when a batch does not converge or the check fails.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from planner.fixed import FixedTrajectory
from planner.first_qp import straight_moves
from planner.result import IterationRecord
from planner.retime import retime_moves
from planner.scenario import Scenario
from planner.scp import ScpOptions, ScpOutcome, run_scp
from planner.solvers import QPSolver
from planner.types import FloatArray, IntArray

__all__ = ["BATCH_VEHICLES", "batch_order", "plan_in_batches"]

#: Vehicles per batch.
BATCH_VEHICLES = 32


def batch_order(scenario: Scenario, size: int = BATCH_VEHICLES) -> list[IntArray]:
    """The batches, in planning order: vehicles sorted by the length of their move, longest
    first (they have the least room to give way), cut into runs of `size`."""
    move = np.linalg.norm((scenario.goals - scenario.starts) / scenario.separation_scale,
                          axis=1)
    order = np.argsort(move, kind="stable").astype(np.intp)
    return [order[lo:lo + size] for lo in range(0, len(order), size)]


def _sub(scenario: Scenario, members: IntArray, fixed: tuple[FixedTrajectory, ...]
         ) -> Scenario:
    """The scenario of `members` only, with `fixed` added to its fixed trajectories."""
    def take(x: FloatArray | None) -> FloatArray | None:
        return None if x is None else x[members]

    return dataclasses.replace(
        scenario, vehicles=tuple(scenario.vehicles[i] for i in members.tolist()),
        starts=scenario.starts[members], goals=scenario.goals[members],
        start_velocities=take(scenario.start_velocities),
        start_accelerations=take(scenario.start_accelerations),
        fixed=scenario.fixed + fixed,
    )


def plan_in_batches(scenario: Scenario, solver: QPSolver, options: ScpOptions | None,
                    batches: list[IntArray],
                    progress: Callable[[IterationRecord], None] | None = None
                    ) -> ScpOutcome | None:
    """Plans `batches` in turn (see the module), or None as soon as one does not converge.
    The outcome's iterations are every batch's, numbered on from one batch to the next."""
    n, stages = len(scenario.vehicles), scenario.steps + 1
    p = np.zeros((n, stages, 3))
    v = np.zeros((n, stages, 3))
    a = np.zeros((n, stages - 1, 3))
    done: list[FixedTrajectory] = []
    history: list[IterationRecord] = []
    first_seconds = 0.0
    straight = straight_moves(scenario)
    pending = np.ones(n, dtype=bool)
    for members in batches:
        pending[members] = False
        sub = _sub(scenario, members, tuple(done))
        guess = None
        if done:
            retimed = retime_moves(sub, straight_moves(sub), force=True)
            guess = None if retimed is None else retimed.guess
        outcome = run_scp(sub, solver, options, guess=guess)
        if outcome.status != "converged":
            return None
        p[members], v[members], a[members] = (outcome.positions, outcome.velocities,
                                              outcome.accelerations)
        first_seconds += outcome.first_qp_seconds
        for rec in outcome.iterations:
            rec = dataclasses.replace(rec, iteration=len(history))
            history.append(rec)
            if progress is not None:
                progress(rec)
        done += [FixedTrajectory(scenario.vehicles[i].id, p[i].copy(), v[i].copy())
                 for i in members.tolist()]
    return ScpOutcome(
        status="converged",
        message=f"planned in {len(batches)} prioritised batches, each converged",
        positions=p, velocities=v, accelerations=a, iterations=history,
        first_qp_seconds=first_seconds,
    )
