"""`plan(scenario) -> Plan`: the planner's one entry point.

Parses the scenario if given as a mapping, runs the SCP loop, derives jerk, thrust and body
rates, verifies the result independently and packs it into a `Plan`. A plan is never
reported `converged` unless its verification passed; if the checks fail (which the loop is
built to prevent) the status becomes `unverified`, with the reason in `message`; so it does
when thrust or body rates exceed the scenario's flyability limits (the QP does not
constrain them).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from planner.dodge import DODGE_MIN_VEHICLES, dodged_moves
from planner.first_qp import solve_first_qp, straight_moves, timed_first_qp
from planner.flatness import body_rates, jerk_from_accelerations, thrust
from planner.prioritized import PrioritizedOutcome, batch_size, plan_batches
from planner.result import IterationRecord, Plan, VehicleTrajectory, Verification
from planner.scenario import Scenario
from planner.scp import ScpOptions, run_scp, thrust_cost
from planner.separated_first import separated_first
from planner.solvers import SOLVED, QPSolver, make_solver
from planner.types import FloatArray
from planner.verify import verify

__all__ = ["plan"]


def _dodges(work: Scenario, options: ScpOptions | None) -> bool:
    """Is the first linearisation point the dodged moves (`planner.dodge`)? Fixed goals,
    large fleets of straight rest-to-rest moves in free space only (routes seed obstacle
    scenarios; fixed trajectories and start velocities are not straight moves' business)."""
    return (options is not None and options.dodge and len(work.vehicles) >= DODGE_MIN_VEHICLES
            and not work.obstacles and not work.fixed and work.start_velocities is None)


def _whole_because(work: Scenario, options: ScpOptions, free: bool, dodged: bool) -> str | None:
    """Why a fleet asked to be planned in prioritized batches (`planner.prioritized`) is
    planned whole, or None when it is not: the batches plan fixed-goal moves of a fleet of
    more than one batch (from rest or a moving state, around its fixed trajectories)."""
    size = batch_size(work, options.batch_size)
    if len(work.vehicles) <= size:
        return f"{len(work.vehicles)} vehicles fit in one batch of {size}"
    if free:
        return "free assignment plans from CAPT's straight moves"
    if dodged:
        return "the dodged first linearisation point was asked for too"
    return None


def _above_free(work: Scenario, backend: QPSolver, accelerations: FloatArray) -> float:
    """How much more thrust cost `accelerations` take than `work`'s separation-free optimum
    (a lower bound on every plan's cost): at most that far from the optimum."""
    free = solve_first_qp(work, backend)
    if free.status != SOLVED:
        return float("inf")
    return thrust_cost(accelerations) - thrust_cost(free.accelerations)


def plan(
    scenario: Scenario | Mapping[str, Any],
    *,
    solver: str | None = None,
    progress: Callable[[IterationRecord], None] | None = None,
    options: ScpOptions | None = None,
) -> Plan:
    """Plan collision-free trajectories for every vehicle of `scenario`.

    solver: 'piqp' (default), 'clarabel' or 'osqp'. progress: called after every SCP
    iteration with its `IterationRecord`. Raises `ScenarioError` for invalid input and
    `SolverError` for an unknown solver; infeasibility is a plan status.

    With `"assignment": "free"` the vehicles fly to the goals of the scenario's assignment
    (`Scenario.goal_order`), and the first SCP iteration is linearised about CAPT's
    synchronised straight moves to them; the plan echoes the scenario as given. With fixed
    goals and `ScpOptions(dodge=True)` a large fleet's first iteration is linearised about
    those moves pushed apart where they crowd (`planner.dodge`); if that plan does not
    converge and verify, it is planned again from the synchronised moves (`progress` then
    sees both runs). With `ScpOptions(decompose="prioritized")` the fleet is planned in
    batches (`planner.prioritized`), and as a whole if a batch fails or the joined plan does
    not verify; the message says which. Under free assignment a separation-free optimum
    that is already separated is the plan, without the loop (`planner.separated_first`).
    """
    began = time.perf_counter()
    spec = scenario if isinstance(scenario, Scenario) else Scenario.from_dict(scenario)
    backend = make_solver(solver)
    if spec.steps_auto:  # the planner chooses the horizon, planning fixed ones
        from planner.horizon_search import search_horizon

        return search_horizon(spec, backend, lambda fixed: plan(
            fixed, solver=solver, progress=progress, options=options))
    work = spec.assigned()
    # iteration 0, solved once: the plan when already separated, else the loop's start
    first_qp = timed_first_qp(work, backend) if spec.assignment == "free" else None
    direct = separated_first(work, *first_qp) if first_qp is not None else None
    guess = straight_moves(work) if spec.assignment == "free" and direct is None else None
    dodged = guess is None and direct is None and _dodges(work, options)
    if dodged:
        found = dodged_moves(work, straight_moves(work))
        dodged = found is not None
        guess = None if found is None else found[0]
    whole_because = (_whole_because(work, options, guess is not None, dodged)
                     if options is not None and options.decompose == "prioritized"
                     and direct is None else None)
    decomposed = (options is not None and options.decompose == "prioritized"
                  and direct is None and whole_because is None)
    batched = (plan_batches(work, backend, options, progress, options.batch_size)
               if decomposed and options is not None else None)
    batches = batched if isinstance(batched, PrioritizedOutcome) else None
    if isinstance(batched, str):
        whole_because = batched
    verification: Verification | None = None
    if direct is not None:
        outcome, verification = direct
        if progress is not None:
            progress(outcome.iterations[0])
    elif batches is not None:
        outcome = batches.outcome
        verification = verify(work, outcome.positions, outcome.velocities,
                              outcome.accelerations)
        if not verification.verified:
            whole_because = ("the joined batches failed verification: "
                             + "; ".join(verification.failures()))
            batches = None
        elif options is not None and options.batch_cost_share:
            above = _above_free(work, backend, outcome.accelerations)
            if not above < work.cost_threshold:
                whole_because = (f"the joined batches cost {above:.3g} above the "
                                 f"separation-free optimum, not less than cost_threshold "
                                 f"{work.cost_threshold:g}")
                batches = None
    if direct is None and batches is None:
        outcome = run_scp(work, backend, options, progress, guess, first_qp)
        if whole_because is not None:
            outcome.message += f"; planned as a whole fleet, not in prioritized batches: " \
                               f"{whole_because}"
        verification = (verify(work, outcome.positions, outcome.velocities,
                               outcome.accelerations)
                        if outcome.status != "infeasible" else None)
    p, v, a = outcome.positions, outcome.velocities, outcome.accelerations
    if dodged and (outcome.status != "converged" or verification is None
                   or not verification.verified):
        # Never a worse plan for having tried: plan again from the synchronised moves.
        outcome = run_scp(work, backend, options, progress, None)
        p, v, a = outcome.positions, outcome.velocities, outcome.accelerations
        verification = verify(work, p, v, a) if outcome.status != "infeasible" else None
    jerk = jerk_from_accelerations(a, spec.dt, spec.start_accelerations)
    f = thrust(a)
    rates = body_rates(a, jerk)
    times: FloatArray = np.arange(spec.steps + 1, dtype=np.float64) * spec.dt
    vehicles = tuple(
        VehicleTrajectory(
            id=vehicle.id, t=times, position=p[n], velocity=v[n], acceleration=a[n],
            jerk=jerk[n], thrust=f[n], body_rates=rates[n],
        )
        for n, vehicle in enumerate(spec.vehicles)
    )
    status, message = outcome.status, outcome.message
    if verification is not None and not verification.verified:
        if status == "converged":
            status = "unverified"
        message = f"{message}; verification failed: {'; '.join(verification.failures())}"
    timing = {
        "total_s": time.perf_counter() - began,
        "first_qp_s": outcome.first_qp_seconds,
    }
    return Plan(
        status=status,
        message=message,
        scenario=spec,
        vehicles=vehicles,
        iterations=tuple(outcome.iterations),
        timing=timing,
        verification=verification,
        solver=backend.name,
        infeasible_groups=outcome.infeasible_groups,
    )
