"""`steps: "auto"`: the shortest horizon, within 10 %, at which the fleet has a verified plan
(Augugliaro, Schoellig & D'Andrea's adaptive horizon, on the scenario's step grid).

The search starts from a lower bound no plan can beat: the fewest steps at which the
vehicles' own separation-free problems are feasible under the velocity, acceleration and jerk
boxes (`relaxed_steps`; tiny QPs of the vehicles with the farthest moves). It plans
(`planner.plan` with fixed steps, passed in as `plan_fixed`) first at the longest horizon
within `TOLERANCE` of that bound, where a verified plan is the answer at once (a crowd may
not plan at the bound itself, and a failing plan can cost more than a converging one: its
solver has to prove the QP infeasible), then at horizons growing by `GROWTH` until one
plan converges and verifies. Then, while that success is more than
`TOLERANCE` longer than the step after the longest failure, it plans at the longest horizon
that would be close enough: a success there ends the search, a failure raises the bound by
`TOLERANCE` (after a `GROWTH` step, at most two such plans). At most `MAX_PLANS` plans are
made. A too-short candidate usually fails fast (its first linearised QP is infeasible).

Bisection assumes a longer horizon never makes a fleet harder to plan, which holds for
the separation-free problem (a vehicle can wait at its start) and in practice for the SCP.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from planner.methods.horizon import fewest_steps
from planner.model.scenario import Scenario
from planner.result import Plan
from planner.scp.qp import SeparationRows, build_group_qp
from planner.scp.solvers import SOLVED, QPSolver
from planner.types import IntArray

__all__ = ["GROWTH", "MAX_PLANS", "TOLERANCE", "Candidate", "relaxed_steps", "search_horizon"]

#: Each failed candidate's horizon times this is the next one tried (before the first
#: success).
GROWTH = 1.25
#: The chosen horizon is at most this much longer than the shortest that verifies.
TOLERANCE = 0.10
#: Most plans one search makes (bounds its work: a few plans of the chosen size).
MAX_PLANS = 10


@dataclass(frozen=True)
class Candidate:
    """One horizon the search planned at."""

    steps: int
    status: str
    """The plan's status; 'converged' only for a plan that also verified."""
    seconds: float
    """Wall time of that plan (s)."""

    def to_dict(self) -> dict[str, Any]:
        return {"steps": self.steps, "status": self.status, "seconds": self.seconds}


def _extremes(work: Scenario) -> IntArray:
    """The vehicles whose own problems bound the fleet's: on each axis the farthest move
    (a shorter rest-to-rest move scales down the longer one's motion, so fits wherever it
    does), and every vehicle that does not start at rest (no such argument for them)."""
    moves = np.abs(work.goals - work.starts)
    chosen = set(np.argmax(moves, axis=0).tolist())
    for state in (work.start_velocities, work.start_accelerations):
        if state is not None:
            chosen.update(np.flatnonzero(np.any(state != 0.0, axis=1)).tolist())
    return np.array(sorted(chosen), dtype=np.intp)


def relaxed_steps(work: Scenario, solver: QPSolver) -> int | None:
    """The fewest steps, from `work.steps` (the velocity/acceleration bound) up to
    `work.max_steps`, at which the separation-free problem of the bounding vehicles
    (`_extremes`) is feasible under every box; None when there is none (feasibility only
    grows with the horizon from rest: `fewest_steps`)."""
    members = _extremes(work)

    def feasible(steps: int) -> bool:
        qp = build_group_qp(work.with_steps(steps), members, SeparationRows.empty())
        return solver.solve(qp).status == SOLVED

    return fewest_steps(feasible, work.steps, work.max_steps)


def _longest_settled(failed: int) -> int:
    """The longest horizon within `TOLERANCE` of the shortest that can verify, which is
    longer than `failed`."""
    return math.floor((1.0 + TOLERANCE) * (failed + 1) + 1e-9)


def _settled(failed: int, succeeded: int) -> bool:
    """Is `succeeded` within `TOLERANCE` of the shortest horizon that can verify?"""
    return succeeded <= _longest_settled(failed)


def search_horizon(spec: Scenario, solver: QPSolver,
                   plan_fixed: Callable[[Scenario], Plan]) -> Plan:
    """Plan `spec` (with `steps_auto`) at the shortest horizon, within `TOLERANCE`, whose
    plan converges and verifies; `plan_fixed` plans one fixed-steps scenario. The plan
    returned carries `horizon` (the candidates tried, the bound, the choice); its scenario
    has the chosen `steps`. When no candidate up to `max_horizon` (or within `MAX_PLANS`)
    verifies, the longest candidate's plan is returned with `horizon.chosen_steps` null and
    a message saying so; without a bound (the boxes allow no horizon up to `max_horizon`)
    the longest horizon is planned once, for the solver's diagnosis."""
    began = time.perf_counter()
    work = spec.assigned()
    cap = spec.max_steps
    bound = relaxed_steps(work, solver)
    tried: list[Candidate] = []

    def attempt(steps: int) -> Plan:
        result = plan_fixed(spec.with_steps(steps))
        status = "converged" if result.ok else ("unverified" if result.status == "converged"
                                                else result.status)
        tried.append(Candidate(steps, status, float(result.timing.get("total_s", 0.0))))
        return result

    failed = (cap if bound is None else bound) - 1  # every horizon under the bound fails
    # the longest horizon within TOLERANCE of the bound: a success there is the answer
    steps = min(cap, _longest_settled(failed))
    best: Plan | None = None
    last = attempt(steps)
    while not last.ok and steps < cap and len(tried) < MAX_PLANS:
        failed = steps
        steps = min(cap, max(steps + 1, math.ceil(steps * GROWTH)))
        last = attempt(steps)
    if last.ok:
        best = last
        while not _settled(failed, steps) and len(tried) < MAX_PLANS:
            # the longest horizon that would settle it: a success there ends the search
            probe = _longest_settled(failed)
            found = attempt(probe)
            if found.ok:
                best, steps = found, probe
            else:
                failed = probe
    else:
        failed = steps
    horizon: dict[str, Any] = {
        "auto": True,
        "chosen_steps": steps if best is not None else None,
        "lower_bound_steps": bound,  # None: the boxes allow no horizon up to max_horizon
        "max_horizon": spec.max_horizon,
        "within_tolerance": best is not None and _settled(failed, steps),
        "tried": [c.to_dict() for c in tried],
    }
    out = best if best is not None else last
    message = out.message
    if best is None:
        why = (f"within {MAX_PLANS} plans" if len(tried) >= MAX_PLANS and steps < cap else
               f"up to max_horizon {spec.max_horizon:g} s ({cap} steps of {spec.dt:g} s)")
        message = (f"no horizon {why} gave a verified plan (tried {_listed(tried)}); "
                   f"the longest: {message}")
    else:
        message = (f"horizon {steps} steps ({steps * spec.dt:g} s) chosen from "
                   f"{_listed(tried)}; {message}")
    timing = {**out.timing, "total_s": time.perf_counter() - began}
    return replace(out, message=message, timing=timing, horizon=horizon)


def _listed(tried: list[Candidate]) -> str:
    """The candidates in words: '40 steps infeasible, 50 converged'."""
    return ", ".join(f"{c.steps} steps {c.status}" for c in tried)
