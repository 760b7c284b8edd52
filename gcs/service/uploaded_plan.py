"""A plan made elsewhere (`fleetplan plan`, another service) brought to the service to be
flown: read, held to the server's work bounds, and verified again on its own trajectories
before it is stored. The file's own verification, jerk, thrust and body rates are claims
(the file may have been edited): they are recomputed from its motion, and a plan that is not
converged, fails the checks or starts moving is refused, naming why."""

from __future__ import annotations

import dataclasses
from typing import Any

from gcs.service.limits import WorkBounds, scenario_bound_errors
from planner.errors import FieldError
from planner.model.flatness import body_rates, jerk_from_accelerations, thrust
from planner.result import Plan
from planner.verification.verify import refusal, verify

__all__ = ["is_plan_body", "plan_document", "uploaded_plan"]


def plan_document(body: Any) -> Any:
    """The plan a request body carries: the body itself, or its `plan` field."""
    if isinstance(body, dict) and set(body) == {"plan"}:
        return body["plan"]
    return body


def is_plan_body(body: Any) -> bool:
    """A plan (a status, a scenario and trajectories) or `{"plan": ...}` rather than a
    scenario or a formation sequence."""
    document = plan_document(body)
    return (isinstance(document, dict) and "status" in document and "scenario" in document
            and "formations" not in document)


def uploaded_plan(body: Any, work: WorkBounds) -> tuple[Plan | None, list[FieldError]]:
    """(the plan, []) when it may be stored and flown, else (None, the problems by field):
    every work bound the scenario it holds exceeds (before any array is read), else a
    malformed field, else the refusal on re-verification (field `plan`)."""
    document = plan_document(body)
    scenario = document.get("scenario") if isinstance(document, dict) else None
    bounds = scenario_bound_errors(scenario, work) if isinstance(scenario, dict) else []
    if bounds:
        return None, [FieldError(f"scenario.{e.field}", e.reason) for e in bounds]
    try:
        plan = _rederived(Plan.from_dict(document))
    except FieldError as exc:
        return None, [exc]
    why = refusal(plan)
    if why is not None:
        return None, [FieldError("plan", f"this plan may not be flown: {why}; plan its "
                                             f"scenario again (fleetplan plan, or the page)")]
    return plan, []


def _rederived(plan: Plan) -> Plan:
    """`plan` with everything derived from its motion computed here: jerk, thrust and body
    rates from the accelerations, the verification from the trajectories."""
    scenario = plan.scenario
    a = plan.accelerations()
    jerk = jerk_from_accelerations(a, scenario.dt, scenario.start_accelerations)
    f, rates = thrust(a), body_rates(a, jerk)
    vehicles = tuple(
        dataclasses.replace(v, jerk=jerk[n], thrust=f[n], body_rates=rates[n])
        for n, v in enumerate(plan.vehicles))
    check = verify(scenario, plan.positions(), plan.velocities(), a)
    return dataclasses.replace(plan, vehicles=vehicles, verification=check)
