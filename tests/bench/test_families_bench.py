"""bench/families.py runs its quick matrix as documented and prints one row per family,
seed and method, every plan verified, with the medians its docs table comes from. Its
timings are not asserted."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench" / "families.py"


def test_the_quick_matrix_plans_every_family_with_every_method_verified() -> None:
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--timeout", "240"],
                          capture_output=True, text=True, timeout=600, cwd="/")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    runs = report["runs"]
    families = {"paper-circle", "antipodal-sphere", "antipodal-circle", "facing-grids",
                "window-rooms", "forest-hold"}
    assert {r["family"] for r in runs} == families
    assert {(r["family"], r["method"]) for r in runs} == {
        (f, m) for f in families for m in ("auto", "whole", "prioritized")}
    for row in runs:
        assert row["status"] == "converged" and row["verified"] is True, row
        assert row["vehicles"] == row["size"] and row["iterations"] >= 1
        assert row["cpu_s"] > 0 and row["wall_s"] > 0 and row["cost"] >= 0
        assert row["load_before"] >= 0 and row["load_after"] >= 0
    # the bug's shape: the first vehicle of the forest holds in place
    hold = next(r for r in runs if r["family"] == "forest-hold")
    assert hold["scenario"].endswith("-hold") and hold["params"] == {"pillars": 4, "side": 12}
    medians = {(m["family"], m["method"]): m for m in report["medians"]}
    assert set(medians) == {(r["family"], r["method"]) for r in runs}
    for (family, method), cell in medians.items():
        mine = [r for r in runs if (r["family"], r["method"]) == (family, method)]
        assert cell["runs"] == cell["verified"] == len(mine)
        assert cell["cpu_s_median"] == sorted(r["cpu_s"] for r in mine)[len(mine) // 2]


def test_a_case_naming_an_unknown_family_or_no_size_is_refused() -> None:
    for case, words in (("nonsense:4", "unknown family 'nonsense'"),
                        ("antipodal-sphere", "needs a size")):
        done = subprocess.run([sys.executable, str(BENCH), "--cases", case],
                              capture_output=True, text=True, timeout=120, cwd="/")
        assert done.returncode != 0 and words in done.stderr
        assert "Traceback" not in done.stderr
