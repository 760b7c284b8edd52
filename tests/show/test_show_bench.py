"""`bench/show.py` runs as documented and prints the figures the docs quote (timings are
not asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench" / "show.py"


def test_the_show_benchmark_reports_every_stage() -> None:
    done = subprocess.run([sys.executable, str(BENCH), "--vehicles", "12", "--repeats", "1",
                           "--workers", "1", "--grid", "2", "0.8"], capture_output=True,
                          text=True, timeout=300, cwd="/")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    [row] = report["sizes"]
    assert row["vehicles"] == 12 and row["plan_ok"] is True and row["report_passed"] is True
    assert row["takeoff_waves"] == 2  # rows 0.8 m apart with R = 1 m
    assert row["formations_found"] == 5
    for key in ("plan_s", "plan_cpu_s", "export_s", "report_s", "import_s", "import_cpu_s"):
        assert row[key] >= 0
    assert row["skyc_bytes"] > 0 and row["report_bytes"] > 0
    assert report["machine"]["cpus"] >= 1
