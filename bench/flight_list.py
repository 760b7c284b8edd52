"""Flight list benchmark: how long a mission's flights take to list, with and without events.

Stores one mission with `--flights` finished flights of `--events` events each (a 100-vehicle
flight records about a thousand), then asks the service for the mission's flights as the
page once did (`GET /api/missions/{id}/flights`: every flight with all its events) and as it
does now (`GET /api/flights?mission_id=...`: a page of summaries, events fetched per flight
when one is opened). Prints one JSON document: per request the median wall and CPU time
(`time.process_time`, the client and the server share the process) over `--repeat` runs and
the body's size.

    python bench/flight_list.py
    python bench/flight_list.py --flights 50 --events 2000 --repeat 5
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

# Run as `python bench/flight_list.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.phases import EventKind
from gcs.service.settings import Settings
from gcs.service.statuses import FlightStatus
from gcs.service.store import Store
from tests.api.support import SHORT_CROSSING

KINDS = [k.value for k in EventKind]


def _events(count: int) -> list[dict[str, Any]]:
    """`count` events of the shape a flight records, over 20 vehicles."""
    return [{"t": round(0.05 * i, 3), "vehicle": f"uav{i % 20}", "kind": KINDS[i % len(KINDS)],
             "detail": f"event {i}: mode OFFBOARD, 1.234 m from the plan"} for i in range(count)]


def _store(url: str, flights: int, events: int) -> str:
    """A mission with `flights` completed flights; its id."""
    store = Store(url)
    mission = store.create_mission(SHORT_CROSSING)
    summary = {"completed": True, "goal_error_max": 0.12, "tracking_error_max": 0.4,
               "min_separation_measured": 1.01, "setpoint_rate_hz": 20.0, "jitter_p99_ms": 3.1}
    for _ in range(flights):
        row = store.create_flight(mission.id, "mock")
        store.update_flight(row.id, status=FlightStatus.COMPLETED, events=_events(events),
                            summary=summary, finished=True)
    store.close()
    return mission.id


def _timed(client: TestClient, url: str, repeat: int) -> dict[str, Any]:
    walls, cpus, size = [], [], 0
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        response = client.get(url)
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
        assert response.status_code == 200, response.text
        size = len(response.content)
    return {"url": url, "wall_s_median": round(statistics.median(walls), 4),
            "cpu_s_median": round(statistics.median(cpus), 4), "bytes": size}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=50)
    parser.add_argument("--events", type=int, default=1000, help="events per flight")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        url = f"sqlite:///{Path(folder) / 'fleetplan.db'}"
        mission_id = _store(url, args.flights, args.events)
        settings = Settings(database_url=url, mock_vehicles=0, plan_workers=1,
                            allowed_hosts=["testserver"])
        with TestClient(create_app(settings)) as client:
            client.get(f"/api/missions/{mission_id}/flights")  # warm: plan cache, imports
            full = _timed(client, f"/api/missions/{mission_id}/flights", args.repeat)
            listed = _timed(client, f"/api/flights?mission_id={mission_id}&limit=500",
                            args.repeat)
            first = client.get(listed["url"]).json()["flights"][0]["id"]
            one = _timed(client, f"/api/flights/{first}", args.repeat)
    print(json.dumps({
        "flights": args.flights, "events_per_flight": args.events, "repeat": args.repeat,
        "python": platform.python_version(),
        "mission_flights_with_events": full, "flight_summaries": listed,
        "one_flight_with_events": one,
        "cpu_ratio": round(full["cpu_s_median"] / max(listed["cpu_s_median"], 1e-9), 1),
    }, indent=2))


if __name__ == "__main__":
    main()
