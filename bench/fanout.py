"""Fan-out floors: a mock flight while other clients crowd the service.

Starts `fleetplan serve` with 8 mock vehicles on free ports, plans paper-circle8 (the flight)
and circle16 (what is exported), flies paper-circle8 at 50 Hz and, once the fleet is flying,
at the same time: `--exports` concurrent exports of circle16 at 100 Hz (CSV, or the JSON
document with `--export-format json`), `--streams` event
streams (SSE) on the flight, `--plans` plan submissions (paper-circle4, wait=0), while one
client polls GET /api/status. Prints one JSON document: the flight's status, link losses,
setpoint rate, tick jitter p99 and missed ticks; the answers of each crowd by status code;
the status poll's worst latency; the service's peak RSS. With --repeat R it runs R times and
reports the medians. The floors (docs: Benchmarks) are: the flight completes with 0 link
losses and p99 jitter <= 5 ms, RSS <= 1 GB, every refused request a 503.

    python bench/fanout.py
    python bench/fanout.py --exports 40 --streams 200 --plans 20 --repeat 3 --priority ordinary
    python bench/fanout.py --export-format json
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import httpx
import psutil

from gcs.sim.ports import free_udp_base, mock_port_offsets

ROOT = Path(__file__).resolve().parents[1]
VEHICLES = 8


def _example(name: str) -> dict[str, Any]:
    return json.loads((ROOT / "planner" / "examples" / f"{name}.json").read_text())


def _free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def _wait(predicate: Any, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not await predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out waiting for {what}")
        await asyncio.sleep(0.1)


async def _export(client: httpx.AsyncClient, url: str) -> int:
    async with client.stream("GET", url) as response:
        async for _ in response.aiter_bytes():
            pass
        return response.status_code


async def _stream(client: httpx.AsyncClient, url: str) -> int:
    """Follow an event stream to its end (the flight's `done`); its status code."""
    async with client.stream("GET", url) as response:
        async for _ in response.aiter_bytes():
            pass
        return response.status_code


async def _plan(client: httpx.AsyncClient, scenario: dict[str, Any]) -> int:
    return (await client.post("/api/missions?wait=0", json=scenario)).status_code


async def _answers(coros: list[Any]) -> dict[str, int]:
    """Status codes (or the exception's name) of every request, counted."""
    results = await asyncio.gather(*coros, return_exceptions=True)
    return dict(Counter(str(r) if isinstance(r, int) else type(r).__name__ for r in results))


async def one_run(args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    port = _free_tcp_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT),
           "FLEETPLAN_MOCK_BASE_PORT": str(free_udp_base(mock_port_offsets(VEHICLES))),
           "FLEETPLAN_MOCK_SETTLE_S": "0.5",
           "FLEETPLAN_VEHICLE_THREAD_PRIORITY": args.priority}
    log = (workdir / f"serve-{port}.log").open("wb")
    server = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "serve", "--host", "127.0.0.1", "--port",
         str(port), "--db", f"sqlite:///{workdir / f'bench-{port}.db'}", "--mock",
         str(VEHICLES), "--workers", "2"], cwd=workdir, env=env, stdout=log,
        stderr=subprocess.STDOUT)
    service = psutil.Process(server.pid)
    peak_rss = 0
    limits = httpx.Limits(max_connections=None, max_keepalive_connections=None)
    try:
        async with httpx.AsyncClient(base_url=f"http://127.0.0.1:{port}", timeout=120,
                                     limits=limits) as client:
            async def up() -> bool:
                if server.poll() is not None:
                    raise RuntimeError("fleetplan serve exited; see " + log.name)
                try:
                    return (await client.get("/api/status")).status_code == 200
                except httpx.HTTPError:
                    return False

            await _wait(up, 60, "the service")
            flown = (await client.post("/api/missions?wait=120",
                                       json=_example("paper-circle8"))).json()
            exported = (await client.post("/api/missions?wait=120",
                                          json=_example("circle16"))).json()
            assert flown["status"] == "planned" and exported["status"] == "planned"
            flight = (await client.post(f"/api/missions/{flown['id']}/flights",
                                        json={"rate_hz": 50.0})).json()
            flight_url = f"/api/flights/{flight['id']}"

            async def flying() -> bool:
                live = (await client.get(flight_url)).json()["live"] or {}
                return live.get("phase") == "flying"

            await _wait(flying, 60, "the flight")
            status_latency: list[float] = []
            done = asyncio.Event()

            async def poll_status() -> None:
                nonlocal peak_rss
                while not done.is_set():
                    t0 = time.perf_counter()
                    with contextlib.suppress(httpx.HTTPError):
                        await client.get("/api/status")
                    status_latency.append(time.perf_counter() - t0)
                    with contextlib.suppress(psutil.Error):
                        peak_rss = max(peak_rss, service.memory_info().rss)
                    await asyncio.sleep(0.2)

            poller = asyncio.create_task(poll_status())
            export_url = (f"/api/missions/{exported['id']}/trajectory?rate=100"
                          f"&format={args.export_format}")
            crowds = await asyncio.gather(
                _answers([_export(client, export_url) for _ in range(args.exports)]),
                _answers([_stream(client, flight_url + "/events")
                          for _ in range(args.streams)]),
                _answers([_plan(client, _example("paper-circle4"))
                          for _ in range(args.plans)]),
            )

            async def finished() -> bool:
                return (await client.get(flight_url)).json()["finished_at"] is not None

            await _wait(finished, 180, "the end of the flight")
            done.set()
            await poller
            doc = (await client.get(flight_url)).json()
    finally:
        server.terminate()
        server.wait(30)
        log.close()
    summary = doc["summary"] or {}
    kinds = Counter(e["kind"] for e in doc["events"])
    return {
        "flight": {"status": doc["status"], "link_losses": kinds.get("link_lost", 0),
                   "station_stalls": kinds.get("station_stall", 0),
                   "setpoint_rate_hz": summary.get("setpoint_rate_hz"),
                   "jitter_p99_ms": summary.get("jitter_p99_ms"),
                   "missed_ticks": summary.get("missed_ticks")},
        "exports": crowds[0], "streams": crowds[1], "plans": crowds[2],
        "status_latency_max_ms": round(max(status_latency) * 1e3, 1),
        "service_peak_rss_mb": round(peak_rss / 2**20, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--exports", type=int, default=40)
    parser.add_argument("--streams", type=int, default=200)
    parser.add_argument("--plans", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--export-format", choices=("csv", "json"), default="csv",
                        help="what the exports ask for: the CSV table or the JSON document")
    parser.add_argument("--priority", choices=("ordinary", "realtime"), default="realtime",
                        help="the service's vehicle_thread_priority (realtime: SCHED_RR 1 "
                             "for the vehicle process's thread, where allowed)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="fleetplan-fanout-") as tmp:
        runs = [asyncio.run(one_run(args, Path(tmp))) for _ in range(args.repeat)]
    flights = [r["flight"] for r in runs]
    median = {
        "jitter_p99_ms": statistics.median(f["jitter_p99_ms"] or 0.0 for f in flights),
        "setpoint_rate_hz": statistics.median(f["setpoint_rate_hz"] or 0.0 for f in flights),
        "status_latency_max_ms": statistics.median(r["status_latency_max_ms"] for r in runs),
        "service_peak_rss_mb": statistics.median(r["service_peak_rss_mb"] for r in runs),
    }
    refused = [code for r in runs for crowd in ("exports", "streams", "plans")
               for code in r[crowd] if code not in ("200", "201", "202")]
    print(json.dumps({
        "benchmark": "fanout",
        "scenario": {"vehicles": VEHICLES, "rate_hz": 50, "flight": "paper-circle8",
                     "exports": args.exports,
                     "export": f"circle16 {args.export_format.upper()} at 100 Hz",
                     "streams": args.streams, "plans": args.plans, "repeat": args.repeat,
                     "vehicle_thread_priority": args.priority},
        "median": median,
        "floors": {"completed": all(f["status"] == "completed" for f in flights),
                   "link_losses": sum(f["link_losses"] for f in flights),
                   "jitter_p99_ms_max": max(f["jitter_p99_ms"] or 0.0 for f in flights),
                   "service_peak_rss_mb_max": max(r["service_peak_rss_mb"] for r in runs),
                   "refusals_not_503": sorted(set(c for c in refused if c != "503"))},
        "runs": runs,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
    }, indent=1))


if __name__ == "__main__":
    main()
