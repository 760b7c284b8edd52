"""The service's status sets, each defined once as a StrEnum.

The store writes these values, the service compares against them, the API schemas document
them and `GET /api/status` serves them (field ``statuses``) so the browser page reads them
instead of keeping a copy. A plan's own status (converged, ...) is the planner's:
`planner.result.STATUSES`. StrEnum members are `str`s, so stored rows and JSON carry the
plain value.
"""

from __future__ import annotations

from enum import StrEnum

from gcs.phases import FlightPhase
from planner.result import STATUSES as PLAN_STATUSES

__all__ = [
    "FLIGHT_ACTIVE",
    "FLIGHT_FINISHED",
    "STATUS_OF_PHASE",
    "FlightStatus",
    "MissionStatus",
    "status_of",
    "status_sets",
]


class MissionStatus(StrEnum):
    """A mission is `planning` until its worker answers, then `planned` (whatever the plan's
    own status: converged, max_iterations or infeasible) or `failed` (no plan: the planner
    raised, timed out, was cancelled, or the service stopped)."""

    PLANNING = "planning"
    PLANNED = "planned"
    FAILED = "failed"


class FlightStatus(StrEnum):
    """One flight: `starting` (links opening, arming, climbing), `running`, `paused` (the
    flight clock stopped, every vehicle holding the setpoint of the same plan time),
    `aborting` while the vehicles may be flying; then one final status. `incomplete`: ran to
    its end without completing (a vehicle was landed by the land_faulty policy, or missed its
    goal); `interrupted`: the service stopped during the flight."""

    STARTING = "starting"
    RUNNING = "running"
    PAUSED = "paused"
    ABORTING = "aborting"
    COMPLETED = "completed"
    INCOMPLETE = "incomplete"
    ABORTED = "aborted"
    FAILED = "failed"
    INTERRUPTED = "interrupted"


#: Flight statuses during which the vehicles are (or may be) flying.
FLIGHT_ACTIVE: tuple[FlightStatus, ...] = (
    FlightStatus.STARTING, FlightStatus.RUNNING, FlightStatus.PAUSED,
    FlightStatus.ABORTING,
)
#: Final flight statuses.
FLIGHT_FINISHED: tuple[FlightStatus, ...] = tuple(
    s for s in FlightStatus if s not in FLIGHT_ACTIVE
)


#: The status of a flight while its executor is in each phase: the one place the service's
#: lifecycle (status) and the run's (phase) meet, read through `status_of`. A flight is
#: `starting` until its vehicle process reports a phase past that; a pause and a resume take
#: the status of `paused` and `flying`; the end takes that of the phase the run ended in
#: (`finished`: completed, or incomplete by its summary; an abort: `aborted`; an error:
#: `failed`). `aborting` (an abort asked for, not yet done) and `interrupted` (the service
#: stopped) are the service's own.
STATUS_OF_PHASE: dict[FlightPhase, FlightStatus] = {
    FlightPhase.CREATED: FlightStatus.STARTING,
    FlightPhase.CONNECTING: FlightStatus.STARTING,
    FlightPhase.PREPARING: FlightStatus.STARTING,
    FlightPhase.GATHERING: FlightStatus.STARTING,
    FlightPhase.FLYING: FlightStatus.RUNNING,
    FlightPhase.PAUSED: FlightStatus.PAUSED,
    FlightPhase.FINISHING: FlightStatus.RUNNING,
    FlightPhase.FINISHED: FlightStatus.COMPLETED,
    FlightPhase.ABORTED: FlightStatus.ABORTED,
    FlightPhase.FAILED: FlightStatus.FAILED,
}


def status_of(phase: FlightPhase, completed: bool = True) -> FlightStatus:
    """The status of a flight whose executor is in `phase` (`STATUS_OF_PHASE`); a finished one
    that did not complete (`completed` false: a vehicle landed by land_faulty, a goal missed)
    is `incomplete`."""
    status = STATUS_OF_PHASE[phase]
    if status == FlightStatus.COMPLETED and not completed:
        return FlightStatus.INCOMPLETE
    return status


def status_sets() -> dict[str, dict[str, list[str]]]:
    """Every status set as served by `GET /api/status` (``statuses``): mission statuses,
    flight statuses with the active and finished subsets, and the planner's plan
    statuses."""
    flight = {
        "all": [s.value for s in FlightStatus],
        "active": [s.value for s in FLIGHT_ACTIVE],
        "finished": [s.value for s in FLIGHT_FINISHED],
    }
    return {
        "mission": {
            "all": [s.value for s in MissionStatus],
            "active": [MissionStatus.PLANNING.value],
            "failed": [MissionStatus.FAILED.value],
        },
        "flight": flight,
        "execution": flight,  # the same, under the flight's former name
        "plan": {"all": list(PLAN_STATUSES)},
    }
