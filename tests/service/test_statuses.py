"""A flight's status follows its phase through one table (`STATUS_OF_PHASE`, read by
`status_of`): every phase has a status, the run's statuses are all reached from it, and a
finished flight that did not complete is incomplete."""

from __future__ import annotations

import pytest

from gcs.phases import FlightPhase
from gcs.service.statuses import STATUS_OF_PHASE, FlightStatus, status_of


@pytest.mark.parametrize("phase", list(FlightPhase))
def test_every_phase_has_the_status_of_the_table(phase: FlightPhase) -> None:
    assert status_of(phase) == STATUS_OF_PHASE[phase]


def test_a_finished_flight_is_completed_or_incomplete() -> None:
    assert status_of(FlightPhase.FINISHED) == FlightStatus.COMPLETED
    assert status_of(FlightPhase.FINISHED, completed=False) == FlightStatus.INCOMPLETE


@pytest.mark.parametrize("phase", [p for p in FlightPhase if p != FlightPhase.FINISHED])
def test_only_the_finished_phase_depends_on_completion(phase: FlightPhase) -> None:
    assert status_of(phase, completed=False) == status_of(phase)


def test_every_status_but_the_services_own_comes_from_a_phase() -> None:
    """aborting (asked for, not yet done) and interrupted (the service stopped) are the
    service's; the run's own statuses are all some phase's."""
    reached = {status_of(p, completed) for p in FlightPhase for completed in (True, False)}
    assert set(FlightStatus) - reached == {FlightStatus.ABORTING, FlightStatus.INTERRUPTED}
