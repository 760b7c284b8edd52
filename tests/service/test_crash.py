"""The fault test: plans computing and a flight under way, kill -9 of the service, restart on
the same database. No mission stays `planning`, every mission and the flight are still there,
the flight keeps its events up to the crash and the landing its vehicle process flew after
it, and no planner worker outlives the service."""

from __future__ import annotations

import signal
import threading
from pathlib import Path
from typing import Any

import httpx
import psutil
import pytest

from planner.families.generators import grid_to_sphere
from tests.api.support import QUICK_PAIR, ServiceProcess, example, free_udp_base
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(400)

#: Generous for every request: the service shares the machine with two planner workers.
HTTP_S = 30.0


@pytest.mark.flight
def test_kill_9_loses_nothing_and_leaves_no_worker(tmp_path: Path) -> None:
    env = {"FLEETPLAN_MOCK_BASE_PORT": str(free_udp_base(2)), "FLEETPLAN_MOCK_SETTLE_S": "0.5",
           "FLEETPLAN_PLAN_WORKERS": "1", "FLEETPLAN_MAX_VEHICLES": "256"}
    service = ServiceProcess(tmp_path, "--mock", "2", env=env, quick_mocks=True).start()
    try:
        url = service.base_url
        planned = httpx.post(f"{url}/api/missions?wait=120", json=QUICK_PAIR,
                             timeout=130).json()
        assert planned["status"] == "planned", planned
        flight = httpx.post(f"{url}/api/missions/{planned['id']}/flights",
                               json={"hold_at_goal": 60}, timeout=HTTP_S).json()
        flight_url = f"{url}/api/flights/{flight['id']}"
        # Plans computing concurrently with the flight (large ones that outlast the test).
        created: list[str] = []

        def post(scenario: dict[str, Any]) -> None:
            response = httpx.post(f"{url}/api/missions?wait=0", json=scenario,
                                  timeout=HTTP_S * 2)
            assert response.status_code in (201, 202), response.text
            created.append(response.json()["id"])

        # Two 256-vehicle show transitions with fixed goals (the crowded case: about 12 s
        # each here) and a small plan, all on one planner worker: one computes and the rest
        # wait their turn, so plans are still `planning` at the kill (some 8 s later) however
        # fast the machine is, while the planner takes one core, not two.
        big = [grid_to_sphere(256, seed=seed) for seed in range(2)]
        posters = [threading.Thread(target=post, args=(scenario,))
                   for scenario in (*big, example("paper-circle4"))]
        for thread in posters:
            thread.start()
        for thread in posters:
            thread.join(60)
        assert len(created) == 3
        wait_for(lambda: (httpx.get(flight_url, timeout=HTTP_S).json().get("live") or {})
                 .get("phase") == "flying", "the flight to be flying", 60)
        # What the service has shown so far; the journal writes it within about a second.
        seen = httpx.get(flight_url, timeout=HTTP_S).json()["events"]
        assert seen, "no flight events yet"
        # The journal's first record snapshot (every ~5 s) is stored too.
        wait_for(lambda: httpx.get(flight_url, timeout=HTTP_S).json()["has_record"],
                 "the first record snapshot", 60)
        statuses = {m: httpx.get(f"{url}/api/missions/{m}", timeout=HTTP_S).json()["status"]
                    for m in created}
        assert "planning" in statuses.values(), statuses
        assert service.process is not None
        tree = psutil.Process(service.process.pid).children(recursive=True)
        workers = [p for p in tree if "resource_tracker" not in " ".join(p.cmdline())]
        assert workers, [p.cmdline() for p in tree]  # the planner worker
        service.process.send_signal(signal.SIGKILL)
        service.process.wait(10)
    finally:
        service.stop()
    # Workers exit by themselves once the service is gone (well before the plans would end).
    _, alive = psutil.wait_procs(workers, timeout=30)
    assert [p.cmdline() for p in alive] == []

    with ServiceProcess(tmp_path, "--mock", "0", "--workers", "1") as again:
        url = again.base_url
        missions = httpx.get(f"{url}/api/missions", timeout=HTTP_S).json()
        ids = {m["id"] for m in missions["missions"]}
        assert ids == {planned["id"], *created}
        for mission in missions["missions"]:
            assert mission["status"] != "planning", mission
            if statuses.get(mission["id"]) == "planning":
                assert mission["status"] == "failed"
                assert mission["error"]["reason"] == \
                    "the service stopped before this plan finished"
        stored = httpx.get(f"{url}/api/flights/{flight['id']}", timeout=HTTP_S).json()
        assert stored["status"] == "interrupted"
        # The vehicle process (gone by now, as the workers) landed the fleet after the
        # crash and stored what it did: that landing is in the events and the record.
        assert stored["error"].startswith("the service stopped during this flight; the "
                                          "vehicle process landed the fleet ("), stored["error"]
        # Every event shown before the crash was stored (as the same records, in order).
        assert stored["events"][: len(seen)] == seen
        after = stored["events"][len(seen):]
        assert any(e["kind"] == "abort" and e["detail"] == "the service is stopping: land all"
                   for e in after), after
        assert [e["vehicle"] for e in after if e["kind"] == "landed"] != [], after
        assert stored["has_record"] is True
        record = httpx.get(f"{url}/api/flights/{flight['id']}/record",
                           timeout=HTTP_S).json()
        assert record["events"] == stored["events"]
        assert record["summary"]["completed"] is False
        setpoints = [len(v["setpoints"]["t"]) for v in record["vehicles"]]
        assert len(setpoints) == 2 and min(setpoints) > 0
