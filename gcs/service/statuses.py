"""Execution statuses: the one definition, used by the service, the store and the API schema.

While flying: ``starting`` (links opening, arming, climbing), ``running``, ``paused`` (the
mission clock stopped, every vehicle holding the setpoint of the same plan time), ``aborting``.
Final: ``completed``, ``incomplete`` (ran to its end without completing: a vehicle landed by the
land_faulty policy, or one missed its goal), ``aborted``, ``failed``, ``interrupted`` (the
service stopped during the flight).
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["FINISHED", "LIVE", "ExecutionStatus"]


class ExecutionStatus(StrEnum):
    """An execution's status (see the module docstring)."""

    STARTING = "starting"
    RUNNING = "running"
    PAUSED = "paused"
    ABORTING = "aborting"
    COMPLETED = "completed"
    INCOMPLETE = "incomplete"
    ABORTED = "aborted"
    FAILED = "failed"
    INTERRUPTED = "interrupted"


S = ExecutionStatus
#: Statuses while the flight is under way.
LIVE: tuple[ExecutionStatus, ...] = (S.STARTING, S.RUNNING, S.PAUSED, S.ABORTING)
#: Final statuses.
FINISHED: tuple[ExecutionStatus, ...] = (S.COMPLETED, S.INCOMPLETE, S.ABORTED, S.FAILED,
                                         S.INTERRUPTED)
del S
