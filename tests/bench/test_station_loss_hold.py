"""bench/station_loss.py over a plan whose columns meet: the station lost, every vehicle
hovers on its Hold failsafe, R kept; then landed by plan from a new station, R kept."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"


@pytest.mark.flight
@pytest.mark.timeout(300)
def test_a_station_lost_over_stacked_columns_keeps_r_and_lands_by_plan() -> None:
    done = subprocess.run([sys.executable, str(BENCH / "station_loss.py"), "--plans",
                           "paper-circle4", "--at", "6", "--land-by-plan"],
                          capture_output=True, text=True, timeout=280, cwd="/")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    row = report["plans"]["paper-circle4"]
    assert row["stacked_columns"]["horizontal_m"] < row["R"] - 0.05  # the columns meet
    [run] = row["runs"]
    assert run["hovering"] == ["uav1", "uav2", "uav3", "uav4"] and run["landed"] == 0
    assert run["closest_m"] >= row["R"] - 0.05 and row["kept_r_minus_5cm"] is True
    landing = run["landing_by_plan"]
    assert landing["exit"] == 0 and landing["landed"] == 4 and run["all_down"] is True
    assert landing["closest_m"] >= row["R"] - 0.05
    assert row["landing_by_plan"] == {"closest_m": landing["closest_m"], "all_landed": True,
                                      "kept_r_minus_5cm": True}
