"""The trajectory CSV export is safe to open in a spreadsheet: a text field that a
spreadsheet would run as a formula is neutralised (OWASP), and numbers stay numbers."""

from __future__ import annotations

import csv
import io

import pytest

import planner
from gcs.service.plans import csv_text_field, trajectory_csv
from tests.planner.conftest import load_example

FORMULA_IDS = ["=cmd|' /C calc'!A0", "+SUM(1,2)", "-2+3", "@HYPERLINK(\"x\")"]


@pytest.fixture(scope="module")
def plan() -> planner.Plan:
    data = load_example("paper-circle4")
    for vehicle, vid in zip(data["vehicles"], FORMULA_IDS, strict=True):
        vehicle["id"] = vid
    return planner.plan(data)


def test_ids_that_spreadsheets_run_as_formulas_are_neutralised(plan):
    rows = list(csv.DictReader(io.StringIO(trajectory_csv(plan, 5.0, 10**6))))
    assert {row["vehicle"] for row in rows} == {"'" + vid for vid in FORMULA_IDS}
    numbers = [float(row[c]) for row in rows for c in ("x", "vx", "ax")]
    assert min(numbers) < 0  # negative velocities are written as numbers, not quoted


@pytest.mark.parametrize(
    ("text", "written"),
    [
        ("uav1", "uav1"),
        ("=1+1", "'=1+1"),
        ("+1", "'+1"),
        ("-1", "'-1"),
        ("@A1", "'@A1"),
        ("\tuav", "'\tuav"),
        ("\ruav", "\"'\ruav\""),
        ("a,b", '"a,b"'),
        ('=HYPERLINK("x")', '"\'=HYPERLINK(""x"")"'),
        ("uav-1", "uav-1"),  # only a leading character triggers a spreadsheet
    ],
)
def test_text_fields(text, written):
    assert csv_text_field(text) == written
