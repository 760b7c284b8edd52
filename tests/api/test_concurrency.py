"""Planning runs in worker processes: while a 64-vehicle plan computes, the API keeps answering
quickly. Measured against a real `fleetplan serve` process over HTTP."""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import httpx
import pytest

from tests.api.support import ServiceProcess, example


@pytest.mark.slow
def test_requests_answer_within_50_ms_while_a_64_vehicle_plan_computes(tmp_path: Path) -> None:
    with ServiceProcess(tmp_path, "--mock", "0", "--workers", "1") as service, httpx.Client(
        base_url=service.base_url, timeout=30
    ) as client:
        small = client.post("/api/missions?wait=60", json=example("paper-circle4"))
        assert small.status_code == 201
        small_id = small.json()["id"]

        started = time.monotonic()
        big = client.post("/api/missions?wait=0", json=example("random64"))
        assert big.status_code == 202
        big_id = big.json()["id"]

        paths = ["/api/status", "/api/missions?limit=20", f"/api/missions/{small_id}",
                 f"/api/missions/{big_id}", f"/api/missions/{small_id}/trajectory?rate=20"]
        latencies: list[float] = []
        by_path: dict[str, list[float]] = {p: [] for p in paths}
        progress_seen = 0
        while True:
            for path in paths:
                t0 = time.perf_counter()
                response = client.get(path)
                latencies.append(time.perf_counter() - t0)
                by_path[path].append(latencies[-1])
                assert response.status_code == 200, response.text
            big_mission = response = client.get(f"/api/missions/{big_id}").json()
            progress_seen = max(progress_seen, len(big_mission["progress"]))
            if big_mission["status"] != "planning":
                break
            assert time.monotonic() - started < 600, "the 64-vehicle plan did not finish"
            time.sleep(0.02)
        planning_s = time.monotonic() - started

    assert big_mission["status"] == "planned", big_mission["error"]
    assert big_mission["plan"]["vehicles"] and len(big_mission["plan"]["vehicles"]) == 64
    assert progress_seen >= 1  # iterations were visible while it planned
    latencies.sort()
    p50 = statistics.median(latencies)
    p99 = latencies[int(0.99 * (len(latencies) - 1))]
    print(f"\n64-vehicle plan: {planning_s:.1f} s; {len(latencies)} requests meanwhile: "
          f"p50 {p50 * 1e3:.1f} ms, p99 {p99 * 1e3:.1f} ms, max {latencies[-1] * 1e3:.1f} ms")
    for path, values in by_path.items():
        print(f"  {path}: max {max(values) * 1e3:.1f} ms, median "
              f"{statistics.median(values) * 1e3:.1f} ms")
    assert len(latencies) >= 50, "the plan finished too fast to measure anything"
    # The planner keeps one of this machine's two cores busy, and other test runs may share
    # it: the 50 ms bound is on the 99th percentile, with a looser cap on the single worst.
    assert p50 < 0.025
    assert p99 < 0.050
    assert latencies[-1] < 0.150
