"""What runs inside a planning worker process: `planner.plan` with its progress sent home.

Kept apart from `gcs.api` so a worker imports the planner and nothing of the web stack. The
parent creates one `multiprocessing` queue and hands it to every worker through the pool's
initializer (queues can only be shared by inheritance); each SCP iteration is put on it as
``(job_id, record_dict)``. The plan comes back as JSON text, serialised here so the parent
never spends event-loop time on a multi-megabyte document.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from typing import Any

__all__ = ["finite_json", "init_worker", "run_plan"]

_progress_queue: Any = None


def init_worker(progress_queue: Any) -> None:
    """Pool initializer: keep the progress queue and import the planner once, up front."""
    global _progress_queue
    _progress_queue = progress_queue
    import planner  # noqa: F401  (warm import: the first plan should not pay for it)


def finite_json(value: Any) -> Any:
    """`value` with every non-finite float replaced by None, so the text is strict JSON
    (browsers' JSON.parse rejects Infinity and NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_json(v) for v in value]
    return value


def run_plan(job_id: str, scenario: dict[str, Any], solver: str | None) -> dict[str, Any]:
    """Plan `scenario`; returns {"plan_json", "status", "ok"} or {"error": {field, reason}}.

    Progress goes to the queue as (job_id, record) per iteration, then (job_id, None).
    """
    from planner import FieldError, IterationRecord, PlannerError, plan

    def progress(record: IterationRecord) -> None:
        if _progress_queue is not None:
            _progress_queue.put((job_id, finite_json(asdict(record))))

    try:
        result = plan(scenario, solver=solver, progress=progress)
    except FieldError as exc:
        return {"error": exc.to_dict()}
    except PlannerError as exc:
        return {"error": {"field": None, "reason": f"{type(exc).__name__}: {exc}"}}
    finally:
        # End-of-progress marker: the queue is FIFO per process, so once the parent reads
        # it, every iteration of this job has been delivered.
        if _progress_queue is not None:
            _progress_queue.put((job_id, None))
    text = json.dumps(finite_json(result.to_dict()), allow_nan=False, separators=(",", ":"))
    return {"plan_json": text, "status": result.status, "ok": bool(result.ok)}
