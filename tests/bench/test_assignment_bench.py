"""bench/assignment.py runs as documented and prints the JSON the free-assignment table comes
from: the sparse path's cost against the dense optimum, its certificate and its memory
(timings are not asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"


def test_assignment_benchmark_compares_sparse_with_dense() -> None:
    done = subprocess.run(
        [sys.executable, str(BENCH / "assignment.py"), "--sizes", "300", "--seeds", "0", "1",
         "--families", "grid-sphere", "sideways", "random"],
        capture_output=True, text=True, timeout=300, cwd="/",
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    cases = report["cases"]
    assert {(c["family"], c["seed"], c["method"]) for c in cases} == {
        (f, s, m) for f in ("grid-sphere", "sideways", "random") for s in (0, 1)
        for m in ("sparse", "dense")}
    for case in cases:
        assert case["proven"]
        assert case["cost_ratio_to_dense"] == pytest.approx(1.0, rel=1e-9)
        assert case["peak_rss_mb"] >= case["base_rss_mb"] > 0
        assert case["lower_bound"] <= case["cost"] * (1 + 1e-9)
    sparse = [c for c in cases if c["method"] == "sparse"]
    assert all(c["rounds"] >= 1 and c["edges"] >= 300 for c in sparse)
    assert len(report["summary"]) == 6
    assert all(row["all_proven"] and row["seeds"] == 2 for row in report["summary"])
