"""Show benchmark: a lit show from design to file and back, timed stage by stage.

Makes a show of --vehicles drones (`planner.families.generators.show_formations`: five
formations with free assignment, 2 s holds), taking off from and landing on a ground grid
(--grid spacing, default 2 m) under the first formation, and gives its formations colours
(a colour per position on every other formation, one colour on the rest; fade, hold and
black legs). Then plans it (`plan_sequence`: legs in a local process pool of --workers),
writes the `.skyc` (`gcs.export.skyc.write_skyc`) and the validation report
(`gcs.show.report`), and imports the `.skyc` back (`read_skyc` + `to_sequence`) --repeats
times. Prints one JSON document: per stage wall seconds (median of the repeats for import)
and CPU seconds (planning: this process and its pool's), the plan's status and size, the
file's and the report's bytes, the report's verdict, the formations found again, and the
machine's load average before and after (the machine is shared: compare CPU seconds).

    python bench/show.py
    python bench/show.py --vehicles 1000 --repeats 3 --workers 2
"""

from __future__ import annotations

import argparse
import json
import math
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
from gcs.show.report import report_html
from gcs.show.skyc_reader import read_skyc
from gcs.show.to_sequence import to_sequence
from planner.families.generators import show_formations
from planner.methods.sequence import plan_sequence


def lit_show(vehicles: int, spacing: tuple[float, float]) -> dict[str, Any]:
    """Five formations with colours and every kind of light transition, taking off from and
    landing on a ground grid of `spacing` (m) under the first formation."""
    data = show_formations(vehicles)
    columns = math.ceil(math.sqrt(vehicles))
    rows = math.ceil(vehicles / columns)
    first = np.array(data["formations"][0]["positions"])
    centre = first.mean(axis=0)
    data["takeoff"] = {"homes": [
        [round(centre[0] + (c - (columns - 1) / 2) * spacing[0], 6),
         round(centre[1] + (r - (rows - 1) / 2) * spacing[1], 6)]
        for r, c in (divmod(n, columns) for n in range(vehicles))]}
    data["landing"] = {}
    homes = np.array(data["takeoff"]["homes"])
    low, high = data["limits"]["position_min"], data["limits"]["position_max"]
    data["limits"]["position_min"] = [min(low[0], homes[:, 0].min() - 2),
                                      min(low[1], homes[:, 1].min() - 2), 0.0]
    data["limits"]["position_max"] = [max(high[0], homes[:, 0].max() + 2),
                                      max(high[1], homes[:, 1].max() + 2), high[2]]
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


def measure(vehicles: int, repeats: int, workers: int, spacing: tuple[float, float],
            keep: Path | None) -> dict[str, Any]:
    data = lit_show(vehicles, spacing)
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
        if keep is not None:
            keep.write_bytes(path.read_bytes())
        (text, passed), report_s, report_cpu = _timed(lambda: report_html(plan))
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
        "ground_grid_m": list(spacing),
        "takeoff_waves": int(shown.sequence.ground.takeoff_waves.max()) + 1
        if shown.sequence.ground is not None else 0,
        "plan_status": plan.status, "plan_ok": plan.ok, "steps": plan.scenario.steps,
        "duration_s": plan.scenario.horizon,
        "plan_s": round(plan_s, 2), "plan_cpu_s": round(plan_cpu, 2),
        "plan_workers": workers,
        "export_s": round(export_s, 2), "export_cpu_s": round(export_cpu, 2),
        "plan_and_export_s": round(plan_s + export_s, 2),
        "skyc_bytes": size,
        "report_s": round(report_s, 2), "report_cpu_s": round(report_cpu, 2),
        "report_bytes": len(text.encode()), "report_passed": passed,
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
    parser.add_argument("--grid", type=float, nargs=2, default=[2.0, 2.0], metavar=("DX", "DY"),
                        help="the ground grid's spacing (m)")
    parser.add_argument("--keep", type=Path, help="also write the last .skyc here")
    args = parser.parse_args()
    before = list(os.getloadavg())
    sizes = [measure(n, args.repeats, args.workers, tuple(args.grid), args.keep)
             for n in args.vehicles]
    print(json.dumps({"benchmark": "show", "sizes": sizes, "machine": _machine(before)},
                     indent=2))


def _machine(load_before: list[float]) -> dict[str, Any]:
    """The machine and how busy it was (load average before and after the run)."""
    return {"cpus": os.cpu_count(), "python": platform.python_version(),
            "load_average_before": load_before, "load_average_after": list(os.getloadavg())}


if __name__ == "__main__":
    main()
