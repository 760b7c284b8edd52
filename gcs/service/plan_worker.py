"""What runs as a Dask task on a planning worker: `planner.plan` with its progress sent home.

Kept apart from `gcs.api` so a worker imports the planner and nothing of the web stack (a
worker of an external cluster needs only `planner` and this module). Progress travels as Dask
structured events: the task logs ``{"job", "kind", ...}`` messages on the topic its caller
named (`Worker.log_event`), the scheduler forwards them to the subscribed client
(`Client.subscribe_topic`). Kinds: ``started`` (with the worker's address, so the service
can restart that worker to stop a task that does not stop by itself), ``iteration`` (one SCP
`IterationRecord`), ``working`` (an `IterationProgress` from inside a long iteration) and
``end`` (no more iterations follow).

The task stops cooperatively: after every SCP iteration and every report from inside one it
checks its time limit, its
cancel flag (a `distributed.Event`) and whether the scheduler released it, and raises
`PlanStopped` out of the planner's `progress` callback. The plan comes back as JSON text,
serialised here so the service never spends event-loop time on a multi-megabyte document.
"""

from __future__ import annotations

import io
import logging
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

__all__ = ["PlanOutcome", "PlanStopped", "finite_json", "plan_json", "run_plan", "stitch_sequence",
           "stop_check", "warm"]


class PlanStopped(Exception):
    """Raised from the progress callback: the plan was cancelled or ran out of time."""


@dataclass(frozen=True)
class PlanOutcome:
    """What a planning task returns: a plan, or why there is none (`error`)."""

    plan_json: str | None = None
    """The Plan JSON text (strict JSON), made on the worker."""
    plan: Any = None
    """A sequence leg's `planner.Plan` itself (pickled arrays, no JSON), for the stitch."""
    status: str | None = None
    """The plan's own status (converged, ...)."""
    ok: bool = False
    """The plan converged and verified."""
    error: dict[str, Any] | None = None
    """{"field", "reason"} when there is no plan."""
    stopped: bool = False
    """The error is a cancel or a time limit, not a verdict on the scenario."""
    steps: int | None = None
    """The plan's steps (the planner chooses them for `steps: "auto"` and sequences)."""

    @classmethod
    def failed(cls, reason: str, field: str | None = None, *, stopped: bool = False
               ) -> PlanOutcome:
        return cls(error={"field": field, "reason": reason}, stopped=stopped)


def warm() -> bool:
    """Import the planner now (run on every worker at start: the first plan should not pay):
    the solver stack and the goal assignment, which `import planner` alone leaves for later."""
    import scipy.optimize  # noqa: F401

    import planner.planning  # noqa: F401

    return True


def finite_json(value: Any) -> Any:
    """`value` with every non-finite float replaced by None, so the text is strict JSON
    (browsers' JSON.parse rejects Infinity and NaN)."""
    if isinstance(value, np.generic):  # numpy scalars: plain Python (msgpack, json)
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_json(v) for v in value]
    return value


def _dask_worker() -> Any:
    """The Dask worker running this task, or None when called outside Dask."""
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):
        return None


def stop_check(name: str | None) -> Callable[[], bool]:
    """A cheap `should this task stop?` check, for a task running on a Dask worker (never
    true elsewhere): its named cancel flag (a `distributed.Event`, one scheduler call) is
    set, or the scheduler has released the task itself (its future was dropped), which the
    worker records at once and which no flag timing can miss."""
    worker = _dask_worker()
    if worker is None:
        return lambda: False
    from distributed import Event

    flag = Event(name).is_set if name is not None else (lambda: False)
    key = worker.get_current_task()

    def stop() -> bool:
        task = worker.state.tasks.get(key)
        return task is None or task.state == "cancelled" or bool(flag())

    return stop


def run_plan(
    job_id: str,
    scenario: dict[str, Any],
    solver: str | None,
    *,
    topic: str | None = None,
    time_limit_s: float | None = None,
    cancel_event: str | None = None,
    leg: int | None = None,
    options: Any = None,
) -> PlanOutcome:
    """Plan `scenario`; returns the plan's JSON text and status, or the error.

    `leg`: the scenario is leg `leg` of a formation sequence; every progress message and
    iteration record says so (``"leg": k``), and the plan is returned as JSON all the same.
    `options`: the `planner.scp.loop.ScpOptions` to plan with (None: the defaults).

    A leg's outcome carries the `planner.Plan` itself (`plan`) rather than its JSON text.
    With `topic`, progress goes out as Dask events (see the module docstring). With
    `time_limit_s`, the plan stops after the first SCP iteration that ends past the limit; with
    `cancel_event`, after the first iteration that ends with that Dask Event set.
    """
    from planner import FieldError, IterationProgress, IterationRecord, PlannerError, plan

    began = time.monotonic()
    worker = _dask_worker() if topic is not None else None

    def send(kind: str, **data: Any) -> None:
        if worker is not None:  # "sent": wall clock, to measure delivery (bench/dask_engine)
            try:
                worker.log_event(topic, {"job": job_id, "kind": kind, "sent": time.time(),
                                         **({} if leg is None else {"leg": leg}), **data})
            except TypeError:  # not msgpack-able: a lost progress line, never a lost plan
                logging.getLogger(__name__).exception("progress message dropped")

    send("started", worker=None if worker is None else worker.address)
    cancelled = stop_check(cancel_event)

    def report(kind: str, record: IterationRecord | IterationProgress) -> None:
        row = finite_json(asdict(record))
        send(kind, record=row if leg is None else {**row, "leg": leg})
        if time_limit_s is not None and time.monotonic() - began > time_limit_s:
            raise PlanStopped(f"planning exceeded its time limit of {time_limit_s:g} s")
        if cancelled():
            raise PlanStopped("planning was cancelled")

    try:
        result = plan(scenario, solver=solver, options=options,
                      progress=lambda record: report("iteration", record),
                      within_iterations=lambda step: report("working", step))
    except PlanStopped as exc:
        return PlanOutcome.failed(str(exc), stopped=True)
    except FieldError as exc:
        return PlanOutcome.failed(exc.reason, exc.field)
    except PlannerError as exc:
        return PlanOutcome.failed(f"{type(exc).__name__}: {exc}")
    finally:
        # End-of-progress marker: events of one worker arrive in order, so once the service
        # sees it, every iteration of this job has been delivered.
        send("end")
    if leg is not None:  # for `stitch_sequence`: the Plan itself (pickled: arrays, no JSON)
        return PlanOutcome(plan=result, status=result.status, ok=bool(result.ok))
    text = plan_json(result)
    return PlanOutcome(plan_json=text, status=result.status, ok=bool(result.ok),
                       steps=result.scenario.steps)


def stitch_sequence(sequence: Any, *legs: PlanOutcome) -> PlanOutcome:
    """Stitch the planned legs of `sequence` (a `planner.methods.sequence.FormationSequence`;
    `legs`:
    `run_plan` results in leg order) and verify the whole timeline; returns the flyable plan
    like `run_plan`, or the first leg's error (a stopped leg stops the whole sequence)."""
    from planner import PlannerError
    from planner.methods.sequence import plan_sequence

    for k, result in enumerate(legs):
        if result.error is not None:
            error = dict(result.error)
            if not result.stopped:
                error["reason"] = f"leg {k}: {error['reason']}"
            return replace(result, error=error)
    plans = [result.plan for result in legs]

    def planned(_fn: Any, scenarios: Any, _solvers: Any) -> list[Any]:
        return plans[:len(list(scenarios))]

    try:
        show = plan_sequence(sequence, mapper=planned)
        flyable = show.to_plan()
    except PlannerError as exc:
        field = getattr(exc, "field", None)
        return PlanOutcome.failed(getattr(exc, "reason", str(exc)), field)
    return PlanOutcome(plan_json=plan_json(flyable), status=flyable.status,
                       ok=bool(flyable.ok), steps=flyable.scenario.steps)


def plan_json(plan: Any) -> str:
    """`plan.to_dict()` as strict JSON text, written by `Plan.write_json` straight from the
    arrays (no `tolist`: 7 s of a 2,000-vehicle, five-formation show; a non-finite number
    becomes null)."""
    out = io.StringIO()
    plan.write_json(out)
    return out.getvalue()
