"""Service latency benchmark: request latency and flight timing while a big plan computes.

Starts `fleetplan serve` (python -m gcs.cli.main serve) on a free port with one planner worker
and 4 mock vehicles, plans and flies a short 4-vehicle crossing, and while that flight
streams setpoints at 20 Hz submits a large scenario (default `random64`, 64 vehicles) and
keeps issuing GET requests (status, vehicles, mission list, the flying mission with its plan,
the big mission while planning, a 20 Hz trajectory export) until the plan is done. Prints one
JSON document: planning time, request latency p50/p99/max overall and per path, and the
flight's setpoint rate, send jitter and missed ticks. With --repeat R it runs R times and also
reports the medians. These are the README's figures; the test suite only bounds them loosely.

    python bench/service.py                       # random64 while a mock flight streams
    python bench/service.py --repeat 3
    python bench/service.py --scenario paper-circle8 --flight quick --hold-at-goal 0.5

--flight quick flies the 6 s crossing instead of the 10 s one and --hold-at-goal sets the
flight's hold at the goals (default: the service's): a smaller run, as the tests use.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

# Run as `python bench/service.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import httpx

from gcs.sim.ports import free_udp_base, mock_port_offsets
from tests.api.support import QUICK_CROSSING, SHORT_CROSSING

ROOT = Path(__file__).resolve().parents[1]

#: The API tests' 4-vehicle crossings (one definition), by --flight: 10 s or 6 s of flight.
CROSSINGS: dict[str, dict[str, Any]] = {"short": SHORT_CROSSING, "quick": QUICK_CROSSING}


def _free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[int(q * (len(ordered) - 1))]


def _ms(values: list[float]) -> dict[str, float]:
    return {"p50_ms": round(statistics.median(values) * 1e3, 2),
            "p99_ms": round(_percentile(values, 0.99) * 1e3, 2),
            "max_ms": round(max(values) * 1e3, 2), "requests": len(values)}


def _wait(predicate: Any, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out waiting for {what}")
        time.sleep(0.1)


def one_run(big: dict[str, Any], workdir: Path, crossing: dict[str, Any],
            flight_options: dict[str, Any]) -> dict[str, Any]:
    port = _free_tcp_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT),
           "FLEETPLAN_MOCK_BASE_PORT": str(free_udp_base(mock_port_offsets(4))),
           "FLEETPLAN_MOCK_SETTLE_S": "0.5"}
    log = (workdir / f"serve-{port}.log").open("wb")
    server = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "serve", "--host", "127.0.0.1", "--port",
         str(port), "--db", f"sqlite:///{workdir / f'bench-{port}.db'}", "--mock", "4",
         "--workers", "1"], cwd=workdir, env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60) as client:
            def up() -> bool:
                if server.poll() is not None:
                    raise RuntimeError("fleetplan serve exited; see " + log.name)
                try:
                    return client.get("/api/status").status_code == 200
                except httpx.HTTPError:
                    return False

            _wait(up, 60, "the service")
            small = client.post("/api/missions?wait=60", json=crossing).json()
            flight = client.post(f"/api/missions/{small['id']}/flights",
                                 json=flight_options or None).json()
            flight_url = f"/api/flights/{flight['id']}"
            _wait(lambda: (client.get(flight_url).json()["live"] or {}).get("phase")
                  == "flying", 30, "the flight")

            started = time.monotonic()
            big_id = client.post("/api/missions?wait=0", json=big).json()["id"]
            paths = ["/api/status", "/api/vehicles", "/api/missions?limit=20",
                     f"/api/missions/{small['id']}", f"/api/missions/{big_id}",
                     f"/api/missions/{small['id']}/trajectory?rate=20"]
            by_path: dict[str, list[float]] = {p: [] for p in paths}
            while True:
                for path in paths:
                    t0 = time.perf_counter()
                    client.get(path).raise_for_status()
                    by_path[path].append(time.perf_counter() - t0)
                status = client.get(f"/api/missions/{big_id}").json()["status"]
                if status != "planning":
                    break
                time.sleep(0.02)
            planning_s = time.monotonic() - started
            # finished_at is set when the final status and summary are stored (a live
            # flight's status can read "completed" a moment before its summary exists).
            _wait(lambda: client.get(flight_url).json()["finished_at"] is not None, 120,
                  "the end of the flight")
            doc = client.get(flight_url).json()
    finally:
        server.terminate()
        server.wait(30)
        log.close()
    everything = [v for values in by_path.values() for v in values]
    summary = doc["summary"] or {}
    return {
        "plan_status": status, "planning_s": round(planning_s, 2),
        "latency": _ms(everything),
        "by_path": {path: _ms(values) for path, values in by_path.items()},
        "flight": {"status": doc["status"],
                   "setpoint_rate_hz": summary.get("setpoint_rate_hz"),
                   "jitter_p50_ms": summary.get("jitter_p50_ms"),
                   "jitter_p99_ms": summary.get("jitter_p99_ms"),
                   "missed_ticks": summary.get("missed_ticks")},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="random64",
                        help="bundled example planned meanwhile (planner/examples/NAME.json)")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--flight", choices=sorted(CROSSINGS), default="short",
                        help="the crossing flown: short (10 s, default) or quick (6 s)")
    parser.add_argument("--hold-at-goal", type=float, default=None, metavar="S",
                        help="the flight's hold at the goals (default: the service's)")
    args = parser.parse_args()
    options = {} if args.hold_at_goal is None else {"hold_at_goal": args.hold_at_goal}
    big = json.loads((ROOT / "planner" / "examples" / f"{args.scenario}.json").read_text())
    with tempfile.TemporaryDirectory(prefix="fleetplan-bench-") as tmp:
        runs = [one_run(big, Path(tmp), CROSSINGS[args.flight], options)
                for _ in range(args.repeat)]
    median = {
        "planning_s": statistics.median(r["planning_s"] for r in runs),
        **{f"latency_{k}": statistics.median(r["latency"][k] for r in runs)
           for k in ("p50_ms", "p99_ms", "max_ms")},
        "setpoint_rate_hz": statistics.median(r["flight"]["setpoint_rate_hz"] or 0.0
                                              for r in runs),
        "jitter_p99_ms": statistics.median(r["flight"]["jitter_p99_ms"] or 0.0 for r in runs),
    }
    worst_missed = max(r["flight"]["missed_ticks"] or 0 for r in runs)
    out = {
        "benchmark": "service",
        "scenario": {"planned_meanwhile": args.scenario, "vehicles": len(big["vehicles"]),
                     "flight": "4 mock vehicles, 20 Hz setpoints", "crossing": args.flight,
                     "plan_workers": 1,
                     "repeat": args.repeat},
        "median": median,
        "missed_ticks_max": worst_missed,
        "runs": runs,
        "machine": {"python": platform.python_version(), "platform": platform.platform(),
                    "cpus": os.cpu_count(), "load_average": os.getloadavg()},
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
