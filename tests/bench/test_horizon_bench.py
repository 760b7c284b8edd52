"""`python bench/horizon.py` prints the search's cost against one plan at the horizon it
chose (the figures of docs/benchmarks/planner.md; their values are not asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"


def test_the_horizon_benchmark_reports_the_search_and_the_single_plan():
    done = subprocess.run([sys.executable, str(BENCH / "horizon.py"), "--cases", "circle:4"],
                          capture_output=True, text=True, timeout=300, cwd="/")
    assert done.returncode == 0, done.stderr
    row = json.loads(done.stdout)["cases"][0]
    assert row["case"] == "circle:4" and row["vehicles"] == 4
    assert row["status"] == row["single_status"] == "converged"
    assert row["chosen_steps"] >= row["lower_bound_steps"]
    assert row["plans"] == len(row["tried"]) >= 1
    assert [t["steps"] for t in row["tried"] if t["status"] == "converged"][-1] \
        == row["chosen_steps"]
    assert row["ratio"] == row["search_cpu_s"] / row["single_cpu_s"]
