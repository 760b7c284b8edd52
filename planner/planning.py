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

from planner.first_qp import straight_moves
from planner.flatness import body_rates, jerk_from_accelerations, thrust
from planner.result import IterationRecord, Plan, VehicleTrajectory
from planner.scenario import Scenario
from planner.scp import ScpOptions, run_scp
from planner.solvers import make_solver
from planner.types import FloatArray
from planner.verify import verify

__all__ = ["plan"]


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
    synchronised straight moves to them; the plan echoes the scenario as given.
    """
    began = time.perf_counter()
    spec = scenario if isinstance(scenario, Scenario) else Scenario.from_dict(scenario)
    backend = make_solver(solver)
    work = spec.assigned()
    guess = straight_moves(work) if spec.assignment == "free" else None
    outcome = run_scp(work, backend, options, progress, guess)
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
    verification = verify(work, p, v, a) if outcome.status != "infeasible" else None
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
