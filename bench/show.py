"""Show benchmark: a lit show from design to file and back, timed stage by stage.

Makes a show of --vehicles drones (`planner.families.generators.show_formations`: five
formations with free assignment, 2 s holds) and gives its formations colours (a colour per
position on every other formation, one colour on the rest; fade, hold and black legs), then
plans it (`plan_sequence`: legs in a local process pool of --workers), writes the `.skyc`
(`gcs.export.skyc.write_skyc`), and imports it back (`read_skyc` + `to_sequence`) --repeats
times. Prints one JSON document: per stage wall seconds (median of the repeats for import)
and CPU seconds (planning: this process and its pool's), the plan's status and size, the
file's bytes, the formations found again, and the machine's load average before and after
(the machine is shared: compare CPU seconds and ratios).

    python bench/show.py
    python bench/show.py --vehicles 1000 --repeats 3 --workers 2
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gcs.export.skyc import write_skyc
from gcs.show.skyc_reader import read_skyc
from gcs.show.to_sequence import to_sequence
from planner.families.generators import show_formations
from planner.methods.sequence import plan_sequence


def lit_show(vehicles: int) -> dict[str, Any]:
    """Five formations with colours and every kind of light transition."""
    data = show_formations(vehicles)
    rng = np.random.default_rng(3)
    kinds = ["fade", "hold", "black", "fade"]
    for f, formation in enumerate(data["formations"]):
        if f % 2:
            formation["color"] = rng.integers(0, 256, (vehicles, 3)).tolist()
        else:
            formation["color"] = ["#ff0000", "#00ff00", "#0000ff"][f % 3]
        if f:
            formation["lights"] = kinds[(f - 1) % len(kinds)]
    return data


def _timed(work: Any) -> tuple[Any, float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    out = work()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def _cpu_with_children() -> float:
    """CPU seconds of this process and of its ended children (the legs' pool)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def measure(vehicles: int, repeats: int, workers: int) -> dict[str, Any]:
    data = lit_show(vehicles)
    cpu_before = _cpu_with_children()
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            shown, plan_s, _ = _timed(lambda: plan_sequence(data, mapper=pool.map))
    else:
        shown, plan_s, _ = _timed(lambda: plan_sequence(data))
    plan_cpu = _cpu_with_children() - cpu_before
    plan = shown.to_plan()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "show.skyc"
        size, export_s, export_cpu = _timed(lambda: write_skyc(plan, path))
        runs, cpus, sequence = [], [], {}
        for _ in range(repeats):
            def work() -> dict[str, Any]:
                show = read_skyc(path)
                return to_sequence(show.tracks, name=show.title, file=path.name,
                                   validation=show.validation)
            sequence, wall, cpu = _timed(work)
            runs.append(wall)
            cpus.append(cpu)
    return {
        "vehicles": vehicles, "formations": len(data["formations"]),
        "plan_status": plan.status, "plan_ok": plan.ok, "steps": plan.scenario.steps,
        "duration_s": plan.scenario.horizon,
        "plan_s": round(plan_s, 2), "plan_cpu_s": round(plan_cpu, 2),
        "plan_workers": workers,
        "export_s": round(export_s, 2), "export_cpu_s": round(export_cpu, 2),
        "plan_and_export_s": round(plan_s + export_s, 2),
        "skyc_bytes": size,
        "import_s": round(statistics.median(runs), 3),
        "import_s_runs": [round(r, 3) for r in runs],
        "import_cpu_s": round(statistics.median(cpus), 3),
        "formations_found": len(sequence.get("formations", [])),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, nargs="+", default=[1000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    args = parser.parse_args()
    load_before = list(os.getloadavg())
    sizes = [measure(n, args.repeats, args.workers) for n in args.vehicles]
    print(json.dumps({
        "benchmark": "show",
        "sizes": sizes,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "load_average_before": load_before,
                    "load_average_after": list(os.getloadavg())},
    }, indent=2))


if __name__ == "__main__":
    main()
