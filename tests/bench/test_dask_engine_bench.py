"""bench/dask_engine.py runs as documented and prints the JSON the README's engine figures
come from (timings are not asserted). One run measures a plan and a sequence together (one
embedded cluster); each test reads its part of the report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"


@pytest.fixture(scope="module")
def report() -> dict[str, Any]:
    """The report of one run: paper-circle4 and a 4-vehicle sequence, one repeat, no cancel."""
    done = subprocess.run(
        [sys.executable, str(BENCH / "dask_engine.py"), "--only", "paper-circle4",
         "--repeats", "1", "--cancel", "", "--sequence", "4", "--sequence-assignment", "free"],
        capture_output=True, text=True, timeout=300, cwd="/",
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_dask_engine_benchmark_reports_overhead_and_latency(report: dict[str, Any]) -> None:
    (row,) = report["scenarios"]  # --only: just the scenario named, not the default two
    assert row["scenario"] == "paper-circle4" and row["vehicles"] == 4
    assert row["engine_median_s"] > 0 and row["direct_median_s"] > 0
    # The overhead is what the engine adds to the same plan computed here.
    assert row["overhead_median_s"] == pytest.approx(
        row["engine_median_s"] - row["direct_median_s"], abs=2e-4)
    latency = report["progress_latency_ms"]
    assert latency["messages"] >= 3  # started, iterations, end
    assert latency["median"] is not None and latency["max"] is not None
    assert report["cancel"] is None and report["workers"] == 2


def test_dask_engine_benchmark_plans_a_sequence_through_the_engine(
        report: dict[str, Any]) -> None:
    (row,) = report["sequences"]
    assert row["vehicles"] == 4 and row["legs"] == 2 and row["status"] == "converged"
    assert row["engine_median_s"] > 0 and row["serial_median_s"] > 0
    assert row["serial_over_engine"] == pytest.approx(
        row["serial_median_s"] / row["engine_median_s"], rel=1e-2)
    assert len(row["leg_s"]) == 2 and all(leg > 0 for leg in row["leg_s"])


@pytest.fixture(scope="module")
def long_show() -> dict[str, Any]:
    """A 3-formation show of 6 vehicles on one worker, then on two."""
    done = subprocess.run(
        [sys.executable, str(BENCH / "dask_engine.py"), "--only", "--cancel", "",
         "--repeats", "1", "--sequence", "6", "--formations", "3", "--workers", "1", "2",
         "--orders", "grid,sphere,torus"],
        capture_output=True, text=True, timeout=300, cwd="/",
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_dask_engine_benchmark_compares_worker_counts_on_a_long_show(
        long_show: dict[str, Any]) -> None:
    one, two = long_show["runs"]
    assert (one["workers"], two["workers"]) == (1, 2)
    for run in (one, two):
        (row,) = run["sequences"]
        assert row["order"] == ["grid", "sphere", "torus"] and row["vehicles"] == 6
        assert len(row["leg_durations_s"]) == 2 and len(row["leg_wall_s"][0]) == 2
        assert row["total_median_s"] == pytest.approx(
            row["parse_assign_median_s"] + row["engine_median_s"], abs=2e-3)
        assert row["stitch_task_s"][0] > 0 and row["peak_rss_mb"][0]["total"] > 0
    # the split per part runs once, with the first worker count
    split = one["sequences"][0]["in_process"]
    assert split["status"] == "converged" and len(split["leg_s"]) == 2
    assert two["sequences"][0]["in_process"] is None
    (speedup,) = long_show["sequence_speedup"]
    assert speedup["speedup"]["1"] == 1.0
    assert speedup["speedup"]["2"] == pytest.approx(
        speedup["median_s"]["1"] / speedup["median_s"]["2"], rel=1e-2)
