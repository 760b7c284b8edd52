"""Show export benchmark: how long writing a plan as a Skybrush .skyc takes, and how big it is.

Plans a grid -> sphere transition with free assignment
(`planner.families.generators.grid_to_sphere`,
30 s at dt 0.2) for each --vehicles count, then writes it with `gcs.export.skyc.skyc_chunks`
--repeats times. Prints one JSON document: per size the plan's time and status, the export's
median seconds, the file's bytes (and show.json's uncompressed bytes), the keyframes written
against one per step, and the largest piece held in memory at once (bytes); the machine and
its load average.

    python bench/export.py
    python bench/export.py --vehicles 100 1000 --repeats 5
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import statistics
import sys
import time
import zipfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gcs.export.skyc import keyframe_count, skyc_chunks
from planner import plan as make_plan
from planner.families.generators import grid_to_sphere


def measure(vehicles: int, repeats: int) -> dict[str, Any]:
    """Plan one transition of `vehicles`, export it `repeats` times."""
    scenario = {**grid_to_sphere(vehicles), "assignment": "free"}
    plan = make_plan(scenario)
    runs, largest, data = [], 0, b""
    for _ in range(repeats):
        start = time.perf_counter()
        pieces = list(skyc_chunks(plan))
        runs.append(time.perf_counter() - start)
        largest = max(len(p) for p in pieces)
        data = b"".join(pieces)
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        show = json.loads(archive.read("show.json"))
        inflated = archive.getinfo("show.json").file_size
    written = sum(len(d["settings"]["trajectory"]["points"]) for d in show["swarm"]["drones"])
    return {
        "vehicles": vehicles, "steps": plan.scenario.steps, "plan_status": plan.status,
        "plan_ok": plan.ok, "plan_s": round(plan.timing.get("total_s", 0.0), 3),
        "export_s": round(statistics.median(runs), 4),
        "export_s_runs": [round(r, 4) for r in runs],
        "skyc_bytes": len(data), "show_json_bytes": inflated,
        "keyframes": written, "keyframes_one_per_step": keyframe_count(plan),
        "largest_piece_bytes": largest,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    load_before = list(os.getloadavg())
    sizes = [measure(n, args.repeats) for n in args.vehicles]
    print(json.dumps({
        "benchmark": "export",
        "sizes": sizes,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "load_average_before": load_before,
                    "load_average_after": list(os.getloadavg())},
    }, indent=2))


if __name__ == "__main__":
    main()
