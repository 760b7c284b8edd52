"""A mission's flights listed as summaries (GET /api/flights?mission_id=...): that mission's
only, newest first, each with its event count but not its events, which the flight's own
document carries; the list the page opens a mission with."""

from __future__ import annotations

from fastapi.testclient import TestClient

from gcs.service.statuses import FlightStatus
from gcs.service.store import Store
from tests.api.support import QUICK_CROSSING


def _events(count: int) -> list[dict[str, object]]:
    return [{"t": 0.1 * i, "vehicle": "a", "kind": "mode", "detail": f"mode {i}"}
            for i in range(count)]


def test_a_mission_s_flights_are_listed_with_event_counts_and_no_events(
        client: TestClient) -> None:
    store: Store = client.app.state.store  # type: ignore[attr-defined]
    mine, other = (store.create_mission({**QUICK_CROSSING, "name": n}) for n in ("mine", "other"))
    flown = []
    for count in (3, 0, 7):
        row = store.create_flight(mine.id, "mock")
        store.update_flight(row.id, status=FlightStatus.COMPLETED, events=_events(count),
                            summary={"completed": True}, finished=True)
        flown.append((row.id, count))
    store.create_flight(other.id, "mock")

    page = client.get("/api/flights", params={"mission_id": mine.id, "limit": 2}).json()
    assert (page["total"], page["limit"], page["offset"]) == (3, 2, 0)
    listed = page["flights"]
    assert [f["id"] for f in listed] == [fid for fid, _ in reversed(flown)][:2]
    assert all("events" not in f and f["mission_id"] == mine.id for f in listed)
    assert [f["event_count"] for f in listed] == [7, 0]
    rest = client.get("/api/flights", params={"mission_id": mine.id, "offset": 2}).json()
    assert [(f["id"], f["event_count"]) for f in rest["flights"]] == [flown[0]]
    # The flight's own document has the events; the mission's old list is unchanged.
    assert len(client.get(f"/api/flights/{flown[2][0]}").json()["events"]) == 7
    old = client.get(f"/api/missions/{mine.id}/flights").json()
    assert [len(f["events"]) for f in old] == [7, 0, 3]
    unknown = client.get("/api/flights", params={"mission_id": "nope"}).json()
    assert (unknown["total"], unknown["flights"]) == (0, [])
    everyone = client.get("/api/flights").json()
    assert everyone["total"] == 4
