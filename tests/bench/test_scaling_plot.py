"""bench/scaling_plot.py draws the README's scaling plot from bench/planner.py JSON: a valid SVG
with one line per (family, assignment, group QP method) and a point per fleet size; the
--group-qp option of the planner benchmark is reported per family row."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"
SVG = "{http://www.w3.org/2000/svg}"


def _plot(tmp_path: Path, report: dict) -> ET.Element:
    """The SVG root that scaling_plot.py draws from `report` (its exit checked)."""
    source = tmp_path / "report.json"
    source.write_text(json.dumps(report))
    out = tmp_path / "plot.svg"
    done = subprocess.run([sys.executable, str(BENCH / "scaling_plot.py"), str(source),
                           "-o", str(out)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return ET.parse(out).getroot()


def test_plot_has_a_line_per_series_and_a_point_per_size(tmp_path):
    report = {"families_summary": [
        {"family": "grid-sphere", "assignment": "fixed", "group_qp": "dual", "vehicles": n,
         "total_s_median": t} for n, t in ((25, 0.5), (100, 3.0), (256, 15.0))
    ] + [
        {"family": "random-dense", "assignment": "fixed", "group_qp": "primal",
         "vehicles": 256, "total_s_median": 20.0},
    ]}
    root = _plot(tmp_path, report)
    lines = root.findall(f"{SVG}polyline")
    assert len(lines) == 2
    assert len(lines[0].get("points").split()) == 3
    # The primal series is dashed; a larger time is drawn higher (smaller y).
    assert lines[1].get("stroke-dasharray")
    ys = [float(p.split(",")[1]) for p in lines[0].get("points").split()]
    assert ys[0] > ys[1] > ys[2]
    titles = [c.find(f"{SVG}title").text for c in root.findall(f"{SVG}circle")]
    assert any("256 vehicles, 15.00 s" in t for t in titles)


def test_plot_refuses_reports_without_families(tmp_path):
    source = tmp_path / "empty.json"
    source.write_text(json.dumps({"scenarios": []}))
    done = subprocess.run([sys.executable, str(BENCH / "scaling_plot.py"), str(source),
                           "-o", str(tmp_path / "plot.svg")], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode != 0
    assert "families_summary" in done.stderr
    assert not (tmp_path / "plot.svg").exists()


def test_planner_benchmark_reports_the_group_qp_method():
    done = subprocess.run([sys.executable, str(BENCH / "planner.py"), "--only", "--dmpc-sizes",
                           "--no-solver-comparison", "--row-modes", "--repeats", "1",
                           "--grid-sphere", "9", "--assignment", "fixed", "--no-memory",
                           "--group-qp", "primal"],
                          capture_output=True, text=True, timeout=300, cwd="/")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["families"][0]["group_qp"] == "primal"
    assert report["families_summary"][0]["group_qp"] == "primal"
    assert report["families_summary"][0]["verified"] == 1


def test_prioritized_runs_draw_a_batches_line_of_median_wall_times(tmp_path):
    runs = [{"case": f"gs:{n}:{seed}", "method": "prioritized-auto", "vehicles": n,
             "verified": True, "wall_s": t} for n, seed, t in
            ((256, 0, 3.0), (256, 1, 5.0), (1000, 0, 30.0))]
    runs += [{"case": "gs:256:0", "method": "whole", "vehicles": 256, "verified": True,
              "wall_s": 99.0},
             {"case": "gs:1000:1", "method": "prioritized-auto", "vehicles": 1000,
              "verified": False, "wall_s": 1.0},
             {"case": "sideways:100:none", "method": "prioritized-auto", "vehicles": 100,
              "verified": True, "wall_s": 2.0}]
    root = _plot(tmp_path, {"runs": runs})
    lines = root.findall(f"{SVG}polyline")
    assert len(lines) == 1  # whole-fleet, unverified and sideways runs draw nothing
    assert len(lines[0].get("points").split()) == 2
    titles = [c.find(f"{SVG}title").text for c in root.findall(f"{SVG}circle")]
    assert titles == ["grid → sphere, fixed, prioritized batches: 256 vehicles, 4.00 s",
                      "grid → sphere, fixed, prioritized batches: 1000 vehicles, 30.00 s"]
