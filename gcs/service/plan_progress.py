"""A plan's progress as the page and clients poll it: how long it has run, the last SCP
iteration, the work done inside the iteration under way, and an estimate of the time left
where one can honestly be made (prioritized batches: the batches left at the mean time of
those done; a whole fleet's SCP has no such measure, so none is given)."""

from __future__ import annotations

from typing import Any

__all__ = ["planning_summary"]


def planning_summary(progress: list[dict[str, Any]], working: dict[str, Any] | None,
                     elapsed_s: float | None) -> dict[str, Any]:
    """{elapsed_s, iterations, last, working, batches: {done, total, remaining_s} | null}
    from the iteration records received (`progress`), the last progress report from inside
    an iteration (`working`, or None) and the seconds since a worker began."""
    last = progress[-1] if progress else None
    return {
        "elapsed_s": None if elapsed_s is None else round(elapsed_s, 3),
        "iterations": len(progress),
        "last": last,
        "working": working,
        "batches": _batches(progress, working, elapsed_s),
    }


def _batches(progress: list[dict[str, Any]], working: dict[str, Any] | None,
             elapsed_s: float | None) -> dict[str, Any] | None:
    """Prioritized batches done of how many, and the time left at the mean time per batch
    so far (None until one batch is done)."""
    latest = next((r for r in ([working] if working else []) + progress[::-1]
                   if r.get("batch") is not None), None)
    if latest is None:
        return None
    total, current = int(latest["batches"]), int(latest["batch"])
    done = current - 1
    remaining = (None if elapsed_s is None or done < 1
                 else round(elapsed_s / done * (total - done), 1))
    return {"done": done, "total": total, "remaining_s": remaining}
