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

--formations F: instead, a long show of F formations (`planner.families.generators.show_formations`,
free assignment) for every --orders entry (shapes joined by commas, cycled to F) and --seeds;
each row adds the parse (the free assignments, as the API does before submitting), each
leg's wall time on its worker, the stitch task's time, the whole (parse + engine), and the
peak RSS of the service and its workers. With several --workers counts each runs on its own
cluster, and `sequence_speedup` gives each show's median total over one worker against more:

    python bench/dask_engine.py --only --cancel '' --repeats 1 --sequence 2000 \
        --formations 5 --workers 1 2 --seeds 0 1
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
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

# Run as `python bench/dask_engine.py`, this folder comes first on sys.path, where planner.py
# (the planner benchmark) would shadow the planner package: the project root goes first.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import planner
from gcs.service.planning import PlanningService
from gcs.service.store import Store
from planner.families.generators import SHOW_SHAPES, show_formations, show_sequence
from planner.methods.sequence import parse_sequence, plan_leg, plan_sequence, timeline_scenario

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


#: The formation orders of --formations by default: the shapes in their own order, and
#: another one starting from the horizontal grid.
ORDERS = (",".join(SHOW_SHAPES[:5]), "carpet,sphere,cube,torus,grid")


@contextmanager
def peak_rss() -> Iterator[dict]:
    """Samples this process and its descendants (the workers) every 0.1 s; the dict it
    yields receives the peaks in MB: `total` (all together) and `largest` (one process)."""
    import psutil

    me = psutil.Process()
    peaks = {"total": 0.0, "largest": 0.0}
    stop = threading.Event()

    def sample() -> None:
        while True:  # at once, every 0.1 s, and once more at the end
            sizes = []
            for proc in [me, *me.children(recursive=True)]:
                with suppress(psutil.Error):
                    sizes.append(proc.memory_info().rss / 2**20)
            peaks["total"] = max(peaks["total"], sum(sizes))
            peaks["largest"] = max(peaks["largest"], max(sizes, default=0.0))
            if stop.is_set():
                return
            stop.wait(0.1)

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    try:
        yield peaks
    finally:
        stop.set()
        thread.join()
        peaks.update({key: round(value, 1) for key, value in peaks.items()})


def in_process(sequence, serial: list[float]) -> dict:
    """The show planned here, one part after the other: each leg, the stitch with the
    whole-timeline verification, the flyable plan, its JSON (as the stitch task makes it)."""
    from gcs.service.plan_worker import plan_json

    t = time.perf_counter()
    legs = [plan_leg(leg) for leg in sequence.legs]
    legs_s = time.perf_counter() - t
    t = time.perf_counter()
    show = plan_sequence(sequence, mapper=lambda _f, scenarios, _s: legs[:len(list(scenarios))])
    stitch_s = time.perf_counter() - t
    t = time.perf_counter()
    flyable = show.to_plan()
    to_plan_s = time.perf_counter() - t
    t = time.perf_counter()
    size = len(plan_json(flyable))
    json_s = time.perf_counter() - t
    serial.append(legs_s + stitch_s + to_plan_s + json_s)
    return {"status": show.status, "leg_s": [round(leg.timing["total_s"], 3) for leg in legs],
            "legs_s": round(legs_s, 3), "stitch_verify_s": round(stitch_s, 3),
            "to_plan_s": round(to_plan_s, 3), "json_s": round(json_s, 3),
            "json_mb": round(size / 1e6, 1),
            "min_separation_continuous": show.verification.min_separation_continuous,
            "dynamics_error": show.dynamics_error}


async def show_row(service: PlanningService, store: Store, messages: list, workers: int,
                   n: int, formations: int, order: str, seed: int, repeats: int,
                   serial: bool) -> dict:
    """A long show through the engine: parse (the free assignments) here, then legs as
    parallel tasks and the stitch task; per-leg wall times from the workers' progress."""
    shapes = order.split(",")
    data = show_formations(n, [shapes[f % len(shapes)] for f in range(formations)], seed=seed)
    totals, parses, engines, legs_runs, stitches, peaks = [], [], [], [], [], []
    split = None
    for _ in range(repeats):
        with peak_rss() as peak:
            t = time.perf_counter()
            sequence = parse_sequence(data)
            parse_s = time.perf_counter() - t
            row = store.create_mission(timeline_scenario(sequence).to_dict())
            began = time.perf_counter()
            job = service.submit_sequence(row.id, sequence)
            await job.done.wait()
            done_wall = time.time()
            engine_s = time.perf_counter() - began
        assert job.outcome is not None and job.outcome["status"] == "planned", job.outcome
        assert job.outcome["plan_ok"], job.outcome
        mine = [m for m in messages if m.get("job") == job.key and "leg" in m]
        starts = {m["leg"]: m["sent"] for m in mine if m["kind"] == "started"}
        ends = {m["leg"]: m["sent"] for m in mine if m["kind"] == "end"}
        legs_runs.append([round(ends[k] - starts[k], 3) for k in sorted(ends)])
        stitches.append(done_wall - max(ends.values()))
        parses.append(parse_s)
        engines.append(engine_s)
        totals.append(parse_s + engine_s)
        peaks.append(dict(peak))
    if serial:
        runs: list[float] = []
        split = in_process(parse_sequence(data), runs)
    return {
        "sequence": data["name"], "vehicles": n, "formations": formations,
        "order": [f["name"] for f in data["formations"]], "seed": seed,
        "leg_durations_s": [f["duration"] for f in data["formations"][1:]],
        "workers": workers, "repeats": repeats,
        "total_median_s": round(statistics.median(totals), 3),
        "total_s_runs": [round(x, 3) for x in totals],
        "parse_assign_median_s": round(statistics.median(parses), 3),
        "engine_median_s": round(statistics.median(engines), 3),
        "leg_wall_s": legs_runs,
        "stitch_task_s": [round(x, 3) for x in stitches],
        "peak_rss_mb": peaks,
        "in_process": split,
        "load_1min": round(os.getloadavg()[0], 2),
    }


async def measure(names: list[str], repeats: int, workers: int, cancel_case: str | None,
                  sequences: list[int] = (), assignment: str = "fixed", formations: int = 0,
                  orders: list[str] = ORDERS, seeds: list[int] = (0,),
                  serial: bool = True) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        store = Store(f"sqlite:///{tmp}/bench.db")
        began = time.perf_counter()
        service = PlanningService(store, workers=workers, solver=None)
        await service.start()
        start_s = time.perf_counter() - began
        latencies: list[float] = []
        messages: list[dict] = []

        def on_message(message: dict) -> None:
            latencies.append(time.time() - message["sent"])
            messages.append(message)

        service.on_message = on_message
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
            if formations:
                sequence_rows = [await show_row(service, store, messages, workers, n,
                                                formations, order, seed, repeats, serial)
                                 for n in sequences for order in orders for seed in seeds]
            else:
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
    parser.add_argument("--formations", type=int, default=0,
                        help="--sequence sizes as long shows of this many formations")
    parser.add_argument("--orders", nargs="+", default=list(ORDERS),
                        help="formation orders, shapes joined by commas "
                             f"({', '.join(SHOW_SHAPES)})")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0],
                        help="long shows: seeds turning each formation about the vertical")
    parser.add_argument("--no-serial", action="store_true",
                        help="long shows: skip the in-process run split per part")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--workers", type=int, nargs="+", default=[2],
                        help="worker processes; several: one cluster each, compared")
    parser.add_argument("--cancel", default="random128",
                        help="scenario cancelled while planning ('' to skip)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    reports = [asyncio.run(measure(args.only, args.repeats, workers, args.cancel or None,
                                   args.sequence, args.sequence_assignment, args.formations,
                                   args.orders, args.seeds, serial=not args.no_serial
                                   and workers == args.workers[0]))
               for workers in args.workers]
    if len(reports) == 1:
        print(json.dumps(reports[0], indent=2))
        return
    print(json.dumps({"benchmark": "dask_engine", "runs": reports,
                      "sequence_speedup": speedups(reports)}, indent=2))


def speedups(reports: list[dict]) -> list[dict]:
    """Per show: the median total with each worker count, and the first count's over each."""
    out = []
    for rows in zip(*(report["sequences"] for report in reports), strict=True):
        key = "total_median_s" if "total_median_s" in rows[0] else "engine_median_s"
        totals = {str(report["workers"]): row[key]
                  for row, report in zip(rows, reports, strict=True)}
        base = rows[0][key]
        out.append({"sequence": rows[0]["sequence"], "median_s": totals,
                    "speedup": {w: round(base / t, 3) for w, t in totals.items()}})
    return out


if __name__ == "__main__":
    main()
