"""bench/chaos.py runs as documented and prints its JSON: one case through the faulty-link
proxy, with the outcome, the true closest approach against R and what the record kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"


@pytest.mark.flight
@pytest.mark.timeout(300)
def test_chaos_benchmark_reports_a_case() -> None:
    done = subprocess.run([sys.executable, str(BENCH / "chaos.py"), "--case", "loss20_after"],
                          capture_output=True, text=True, timeout=280, cwd="/",
                          env=dict(os.environ))
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["plan"] == "paper-circle4" and report["R_m"] == 1.0
    [case] = report["cases"]
    assert case["case"] == "loss20_after" and case["run"] == 0
    assert case["held"] == (case["closest_m"] >= 0.95)
    assert 0.0 < case["closest_m"] < 10.0
    assert case["record"]["events"].get("link_degraded", 0) >= 1
    assert set(case["record"]["link_quality"]) == {"uav1", "uav2", "uav3", "uav4"}
