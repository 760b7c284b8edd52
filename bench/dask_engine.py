"""Planning-engine benchmark: what running plans as Dask tasks costs over calling the planner.

Starts the service's `PlanningService` on an embedded LocalCluster (WORKERS processes) and
reports, as one JSON document: cluster start time; for each scenario the median wall time of a
plan through the engine (submit -> stored) against `planner.plan` in this process, and the
difference (the engine's overhead); the delivery latency of progress messages from the worker
to the service (worker wall clock at send -> arrival on the service's event loop, same
machine) as median and max; and how long a cancel takes to end a running large plan and free
its worker.

    python bench/dask_engine.py                      # paper-circle4, circle16; 5 repeats
    python bench/dask_engine.py --repeats 3 --only paper-circle4
    python bench/dask_engine.py --only --cancel '' --sequence 25 36 --sequence-assignment fixed

--sequence N: a grid -> sphere -> grid formation sequence of N vehicles planned through the
engine (its legs as parallel Dask tasks, then the stitch task) against `plan_sequence` here,
legs one after the other; the ratio is serial / engine.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

# Run as `python bench/dask_engine.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import planner
from gcs.service.planning import PlanningService
from gcs.service.store import Store
from planner.generators import show_sequence
from planner.sequence import parse_sequence, plan_sequence, timeline_scenario

EXAMPLES = Path(__file__).resolve().parents[1] / "planner" / "examples"


def scenario(name: str) -> dict:
    return planner.Scenario.from_dict(json.loads((EXAMPLES / f"{name}.json").read_text())
                                      ).to_dict()


async def sequence_row(service: PlanningService, store: Store, n: int, assignment: str,
                       repeats: int) -> dict:
    """One sequence through the engine (legs in parallel) against legs in series here."""
    data = show_sequence(n)
    data["assignment"] = assignment
    sequence = parse_sequence(data)
    engine, serial = [], []
    for _ in range(repeats):
        row = store.create_mission(timeline_scenario(sequence).to_dict())
        t = time.perf_counter()
        job = service.submit_sequence(row.id, sequence)
        await job.done.wait()
        engine.append(time.perf_counter() - t)
        assert job.outcome is not None and job.outcome["status"] == "planned", job.outcome
        t = time.perf_counter()
        result = await asyncio.to_thread(plan_sequence, sequence)
        serial.append(time.perf_counter() - t)
    return {
        "sequence": data["name"], "assignment": assignment, "vehicles": n,
        "legs": len(sequence.legs), "repeats": repeats, "status": result.status,
        "engine_median_s": round(statistics.median(engine), 4),
        "serial_median_s": round(statistics.median(serial), 4),
        "leg_s": [round(leg.timing["total_s"], 3) for leg in result.legs],
        # three significant digits: the ratio is far below 1 on a busy machine
        "serial_over_engine": float(f"{statistics.median(serial) / statistics.median(engine):.3g}"),
    }


async def measure(names: list[str], repeats: int, workers: int, cancel_case: str | None,
                  sequences: list[int] = (), assignment: str = "fixed") -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        store = Store(f"sqlite:///{tmp}/bench.db")
        began = time.perf_counter()
        service = PlanningService(store, workers=workers, solver=None)
        await service.start()
        start_s = time.perf_counter() - began
        latencies: list[float] = []
        service.on_message = lambda m: latencies.append(time.time() - m["sent"])
        rows = []
        try:
            for name in names:
                data = scenario(name)
                engine, direct = [], []
                for _ in range(repeats):
                    row = store.create_mission(data)
                    t = time.perf_counter()
                    job = service.submit(row.id, data)
                    await job.done.wait()
                    engine.append(time.perf_counter() - t)
                    assert job.outcome is not None and job.outcome["status"] == "planned"
                    t = time.perf_counter()
                    await asyncio.to_thread(planner.plan, data)
                    direct.append(time.perf_counter() - t)
                rows.append({
                    "scenario": name, "vehicles": len(data["vehicles"]), "repeats": repeats,
                    "engine_median_s": round(statistics.median(engine), 4),
                    "direct_median_s": round(statistics.median(direct), 4),
                    "overhead_median_s": round(statistics.median(engine)
                                               - statistics.median(direct), 4),
                })
            sequence_rows = [await sequence_row(service, store, n, assignment, repeats)
                             for n in sequences]
            cancel = None
            if cancel_case:
                data = scenario(cancel_case)
                row = store.create_mission(data)
                job = service.submit(row.id, data)
                await job.started.wait()
                await asyncio.sleep(1.0)
                t = time.perf_counter()
                service.cancel(row.id)
                await job.done.wait()
                cancel = {"scenario": cancel_case, "cancel_to_done_s":
                          round(time.perf_counter() - t, 3)}
        finally:
            await service.close()
            store.close()
    return {
        "benchmark": "dask_engine",
        "workers": workers,
        "cluster_start_s": round(start_s, 3),
        "scenarios": rows,
        "sequences": sequence_rows,
        "progress_latency_ms": {
            "messages": len(latencies),
            "median": round(1000 * statistics.median(latencies), 2) if latencies else None,
            "max": round(1000 * max(latencies), 2) if latencies else None,
        },
        "cancel": cancel,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "load_1min": round(os.getloadavg()[0], 2)},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=["paper-circle4", "circle16"])
    parser.add_argument("--sequence", type=int, nargs="*", default=[],
                        help="grid -> sphere -> grid sequences of these sizes")
    parser.add_argument("--sequence-assignment", choices=("fixed", "free"), default="fixed")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--cancel", default="random128",
                        help="scenario cancelled while planning ('' to skip)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    report = asyncio.run(measure(args.only, args.repeats, args.workers, args.cancel or None,
                                 args.sequence, args.sequence_assignment))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
