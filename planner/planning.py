"""`plan(scenario) -> Plan`: the planner's one entry point.

Parses the scenario if given as a mapping, runs its method's table of stages
(`planner.methods.stages`; each stage's plan verified independently), derives jerk, thrust and body
rates and packs the result into a `Plan`. A plan is never
reported `converged` unless its verification passed; if the checks fail (which the loop is
built to prevent) the status becomes `unverified`, with the reason in `message`; so it does
when thrust or body rates exceed the scenario's flyability limits (the QP does not
constrain them).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from planner.errors import ScenarioError
from planner.methods.portfolio import AUTO_TABLE
from planner.methods.stages import Context, TableResult, run_table, table_for
from planner.model.flatness import body_rates, jerk_from_accelerations, thrust
from planner.model.scenario import METHODS, Scenario
from planner.options import PlanningOptions, ScpOptions
from planner.result import (
    Attempt,
    IterationProgress,
    IterationRecord,
    Outcome,
    Plan,
    PlanStatus,
    Progress,
    VehicleTrajectory,
)
from planner.scp.first_qp import straight_moves, timed_first_qp
from planner.scp.solvers import make_solver
from planner.types import FloatArray

__all__ = ["plan"]


def plan(
    scenario: Scenario | Mapping[str, Any],
    *,
    solver: str | None = None,
    progress: Callable[[IterationRecord], None] | None = None,
    options: PlanningOptions | ScpOptions | None = None,
    method: str | None = None,
    within_iterations: Callable[[IterationProgress], None] | None = None,
) -> Plan:
    """Plan collision-free trajectories for every vehicle of `scenario`.

    solver: 'piqp' (default), 'clarabel' or 'osqp'. progress: called after every SCP
    iteration with its `IterationRecord` (labelled with its method). options: the planning
    settings (`PlanningOptions`), or only the SCP loop's (`ScpOptions`). method: 'auto',
    'whole' or 'prioritized', overriding the scenario's `method`. within_iterations: called
    during long SCP iterations, at most about once a second, with an `IterationProgress`
    (groups solved so far; labelled like the records). Raises `ScenarioError` for
    invalid input and `SolverError` for an unknown solver; infeasibility is a plan status.

    The method picks a table of stages (`planner.methods.stages`): under free assignment a
    separation-free optimum that is already separated is the plan, without the loop; with
    fixed goals `prioritized` plans the fleet in batches (`planner.methods.prioritized`) and the
    whole fleet if they fail, `whole` only the whole fleet, and `auto` both at once where
    batches apply (`planner.methods.portfolio`). The plan records the method that produced it and
    every method tried or declined (`Plan.method`, `Plan.attempts`). With free assignment
    the vehicles fly to the goals of the scenario's assignment (`Scenario.goal_order`), the
    whole fleet linearised first about CAPT's synchronised straight moves; the plan echoes
    the scenario as given.
    """
    began = time.perf_counter()
    spec = scenario if isinstance(scenario, Scenario) else Scenario.from_dict(scenario)
    if method is not None:
        if method not in METHODS:
            raise ScenarioError("method", f"must be one of {', '.join(map(repr, METHODS))}, "
                                          f"got {method!r}")
        spec = dataclasses.replace(spec, method=method)
    settings = options if isinstance(options, PlanningOptions) else PlanningOptions(
        scp=options or ScpOptions())
    backend = make_solver(solver)
    if spec.steps_auto:  # the planner chooses the horizon, planning fixed ones
        from planner.methods.horizon_search import search_horizon

        return search_horizon(spec, backend, lambda fixed: plan(
            fixed, solver=solver, progress=progress, options=options,
            within_iterations=within_iterations))
    work = spec.assigned()
    free = spec.assignment == "free"
    # iteration 0, solved once: the plan when already separated, else the loop's start
    ctx = Context(work, free, backend, settings, _split(progress, within_iterations),
                  first_qp=timed_first_qp(work, backend) if free else None)
    ctx.guess = straight_moves(work) if free else None
    table = AUTO_TABLE if spec.method == "auto" else table_for(spec.method)
    result = run_table(table, ctx)
    return _packed(spec, result, backend.name, began)


def _split(progress: Callable[[IterationRecord], None] | None,
           within: Callable[[IterationProgress], None] | None) -> Progress | None:
    """The methods' one progress channel, each kind handed to its own callback."""
    if progress is None and within is None:
        return None

    def told(item: IterationRecord | IterationProgress) -> None:
        if isinstance(item, IterationProgress):
            if within is not None:
                within(item)
        elif progress is not None:
            progress(item)

    return told


def _message(spec: Scenario, result: TableResult) -> str:
    """The plan's message: its outcome's, and why batches asked for did not plan it."""
    assert result.run is not None and result.run.outcome is not None
    message = result.run.outcome.message
    if spec.method == "prioritized" and result.method not in ("prioritized", "separated_first"):
        why = next((a.reason for a in result.attempts if a.method == "prioritized"
                    and a.outcome in (Outcome.DECLINED, Outcome.FAILED)), None)
        if why is not None:
            message += f"; planned as a whole fleet, not in prioritized batches: {why}"
    return message


def _packed(spec: Scenario, result: TableResult, solver: str, began: float) -> Plan:
    """The `Plan` of a table's result: derived jerk, thrust and body rates, the verdict."""
    run = result.run
    assert run is not None and run.outcome is not None  # a table ends with a final stage
    outcome, verification = run.outcome, run.verification
    p, v, a = outcome.positions, outcome.velocities, outcome.accelerations
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
    status, message = outcome.status, _message(spec, result)
    if verification is not None and not verification.verified:
        if status == PlanStatus.CONVERGED:
            status = PlanStatus.UNVERIFIED
        message = f"{message}; verification failed: {'; '.join(verification.failures())}"
    timing = {
        "total_s": time.perf_counter() - began,
        "first_qp_s": outcome.first_qp_seconds,
    }
    iterations = tuple(r if r.method is not None else dataclasses.replace(r, method=result.method)
                       for r in outcome.iterations)
    return Plan(
        status=str(status),
        message=message,
        scenario=spec,
        vehicles=vehicles,
        iterations=iterations,
        timing=timing,
        verification=verification,
        solver=solver,
        infeasible_groups=outcome.infeasible_groups,
        method=result.method,
        attempts=tuple(_rounded(attempt) for attempt in result.attempts),
    )


def _rounded(attempt: Attempt) -> Attempt:
    """An attempt with plain JSON values (its outcome as a string)."""
    return dataclasses.replace(attempt, outcome=str(attempt.outcome),
                               seconds=float(attempt.seconds))
