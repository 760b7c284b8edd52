"""The flight's vocabulary (gcs/phases.py): event kinds renamed since they were stored still
read as the kind they are now, and the published vocabulary carries only current values."""

from __future__ import annotations

from pathlib import Path

from gcs.documents import current_events
from gcs.phases import FORMER_EVENT_KINDS, EventKind, FlightPhase, vocabulary
from gcs.service.statuses import FLIGHT_FINISHED, STATUS_OF_PHASE, FlightStatus
from gcs.service.store import Store
from planner.model.scenario import Scenario
from tests.api.support import example


def test_a_former_event_kind_reads_as_the_current_one() -> None:
    assert EventKind("mission_start") is EventKind.FLIGHT_START
    assert EventKind.FLIGHT_START == "flight_start"
    assert not set(FORMER_EVENT_KINDS) & set(vocabulary()["event_kinds"])
    assert current_events([{"t": 1.0, "vehicle": None, "kind": "mission_start", "detail": "x"},
                           {"t": 2.0, "vehicle": "a", "kind": "landed", "detail": ""}]) == [
        {"t": 1.0, "vehicle": None, "kind": "flight_start", "detail": "x"},
        {"t": 2.0, "vehicle": "a", "kind": "landed", "detail": ""}]


def test_an_event_kind_this_version_does_not_know_is_kept_as_stored() -> None:
    """A record from another version (here a `warning`, a kind the station once emitted)
    still reads: its unknown kind is served as it was stored, not refused."""
    [event] = current_events([{"t": 3.0, "vehicle": "a", "kind": "warning", "detail": "w"}])
    assert event == {"t": 3.0, "vehicle": "a", "kind": "warning", "detail": "w"}
    assert not isinstance(event["kind"], EventKind)


def test_a_flight_stored_with_former_words_loads_in_current_ones(tmp_path: Path) -> None:
    """Events stored as `mission_start` come back as `flight_start`; a record that has only
    `mission_start` (written before `flight_start`) is served as it was stored."""
    store = Store(f"sqlite:///{tmp_path / 'old.db'}")
    mission = store.create_mission(Scenario.from_dict(example("paper-circle2")).to_dict())
    flight = store.create_flight(mission.id, "mock: a, b")
    record = '{"format": "fleetplan-flight-record/2", "mission_start": 1.5, "vehicles": []}'
    store.update_flight(flight.id, status=FlightStatus.COMPLETED, record_json=record,
                        events=[{"t": 1.5, "vehicle": None, "kind": "mission_start",
                                 "detail": "tick 30"}], finished=True)
    loaded = store.get_flight(flight.id, with_record=True)
    store.close()
    assert loaded is not None
    assert [e["kind"] for e in loaded.events] == [EventKind.FLIGHT_START]
    assert loaded.record_json == record


def test_every_flight_phase_has_one_status() -> None:
    """The phase -> status table covers every phase; a flight is `starting` until it flies,
    and a phase that ends the run maps to a final status."""
    assert set(STATUS_OF_PHASE) == set(FlightPhase)
    starting = {p for p, s in STATUS_OF_PHASE.items() if s == FlightStatus.STARTING}
    assert starting == {FlightPhase.CREATED, FlightPhase.CONNECTING, FlightPhase.PREPARING,
                        FlightPhase.GATHERING}
    for phase in (FlightPhase.FINISHED, FlightPhase.ABORTED, FlightPhase.FAILED):
        assert STATUS_OF_PHASE[phase] in FLIGHT_FINISHED
