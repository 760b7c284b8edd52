"""Scaling plot (vehicles against planning time) from benchmark JSON, as a static SVG.

    python bench/scaling_plot.py A.json B.json [C.json ...] -o docs/scaling.svg

Reads each `bench/planner.py` report's `families_summary` (medians over seeds) and each
`bench/prioritized.py` report's prioritized runs of `gs:` and `random:` cases (their median
wall time per size), and draws one line per (family, assignment, method) on log-log axes,
with the drone-show floors as red bars. Written by hand (no plotting dependency): the
project has no matplotlib.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from pathlib import Path
from typing import Any

#: The drone-show and record-scale floors (family, assignment, vehicles, seconds).
FLOORS = [
    ("grid-sphere", "fixed", 100, 10.0),
    ("grid-sphere", "free", 100, 2.0),
    ("grid-sphere", "fixed", 256, 5.0),
    ("grid-sphere", "fixed", 1000, 60.0),
    ("grid-sphere", "free", 1000, 120.0),
    ("random-dense", "fixed", 1000, 5.0),
    ("grid-sphere", "free", 16000, 60.0),
]
COLOURS = ["#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf", "#7f7f7f"]
WIDTH, HEIGHT = 760, 480
LEFT, RIGHT, TOP, BOTTOM = 70, 250, 30, 55
X_RANGE = (16.0, 20000.0)
Y_RANGE = (0.01, 300.0)


def _x(n: float) -> float:
    lo, hi = (math.log10(v) for v in X_RANGE)
    return LEFT + (math.log10(n) - lo) / (hi - lo) * (WIDTH - LEFT - RIGHT)


def _y(t: float) -> float:
    lo, hi = (math.log10(v) for v in Y_RANGE)
    t = min(max(t, Y_RANGE[0]), Y_RANGE[1])
    return HEIGHT - BOTTOM - (math.log10(t) - lo) / (hi - lo) * (HEIGHT - TOP - BOTTOM)


#: A `bench/prioritized.py` case's prefix and the family it names.
CASE_FAMILIES = {"gs": "grid-sphere", "random": "random-dense"}
#: The method of a line drawn from prioritized runs.
BATCHES = "batches"


def _label(family: str, assignment: str, method: str) -> str:
    name = "grid → sphere" if family == "grid-sphere" else "random (random128 density)"
    how = "prioritized batches" if method == BATCHES else f"{method} QPs"
    return f"{name}, {assignment}, {how}"


def _batch_medians(report: dict[str, Any]) -> dict[tuple[str, str, str], dict[int, float]]:
    """The median wall time per size of a `bench/prioritized.py` report's verified
    prioritized runs of the families the plot draws (fixed goals)."""
    times: dict[tuple[str, int], list[float]] = {}
    for run in report.get("runs", []):
        family = CASE_FAMILIES.get(str(run.get("case", "")).split(":")[0])
        if (family is None or not str(run.get("method", "")).startswith("prioritized")
                or not run.get("verified")):
            continue
        times.setdefault((family, int(run["vehicles"])), []).append(float(run["wall_s"]))
    out: dict[tuple[str, str, str], dict[int, float]] = {}
    for (family, n), walls in times.items():
        out.setdefault((family, "fixed", BATCHES), {})[n] = statistics.median(walls)
    return out


def series(reports: list[dict[str, Any]]) -> dict[tuple[str, str, str], list[tuple[int, float]]]:
    """One line per (family, assignment, method): its medians by size. A size measured in
    several reports takes the last report's figure (a later, quieter run)."""
    out: dict[tuple[str, str, str], dict[int, float]] = {}
    for report in reports:
        for row in report.get("families_summary", []):
            key = (row["family"], row["assignment"], row.get("group_qp", "primal"))
            out.setdefault(key, {})[row["vehicles"]] = row["total_s_median"]
        for key, sizes in _batch_medians(report).items():
            out.setdefault(key, {}).update(sizes)
    return {k: sorted(v.items()) for k, v in sorted(out.items())}


def render(lines: dict[tuple[str, str, str], list[tuple[int, float]]], note: str) -> str:
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" '
        f'viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="12">',
        f'<rect width="{WIDTH}" height="{HEIGHT}" fill="white"/>',
    ]
    x0, x1 = _x(X_RANGE[0]), _x(X_RANGE[1])
    y0, y1 = _y(Y_RANGE[0]), _y(Y_RANGE[1])
    for n in (16, 64, 256, 1000, 4000, 16000):
        x = _x(n)
        parts.append(f'<line x1="{x:.1f}" y1="{y0}" x2="{x:.1f}" y2="{y1}" stroke="#ddd"/>')
        parts.append(f'<text x="{x:.1f}" y="{y0 + 16}" text-anchor="middle">{n}</text>')
    for t in (0.01, 0.1, 1, 10, 60, 100):
        y = _y(t)
        parts.append(f'<line x1="{x0}" y1="{y:.1f}" x2="{x1}" y2="{y:.1f}" stroke="#ddd"/>')
        parts.append(f'<text x="{x0 - 6}" y="{y + 4:.1f}" text-anchor="end">{t:g}</text>')
    parts.append(f'<rect x="{x0}" y="{y1}" width="{x1 - x0}" height="{y0 - y1}" '
                 'fill="none" stroke="#333"/>')
    parts.append(f'<text x="{(x0 + x1) / 2}" y="{HEIGHT - 18}" text-anchor="middle">'
                 'vehicles (log)</text>')
    parts.append(f'<text transform="translate(18,{(y0 + y1) / 2}) rotate(-90)" '
                 'text-anchor="middle">planning time, s (log; median over seeds)</text>')
    parts.append(f'<text x="{x0}" y="{TOP - 12}">{note}</text>')
    for family, assignment, n, seconds in FLOORS:
        x, y = _x(n), _y(seconds)
        parts.append(f'<line x1="{x - 9:.1f}" y1="{y:.1f}" x2="{x + 9:.1f}" y2="{y:.1f}" '
                     f'stroke="#d62728" stroke-width="3"><title>floor: {family} {assignment} '
                     f'{n}: {seconds:g} s</title></line>')
    legend_y = TOP + 10
    for index, (key, points) in enumerate(lines.items()):
        colour = COLOURS[index % len(COLOURS)]
        dash = {"primal": ' stroke-dasharray="5,4"',
                BATCHES: ' stroke-dasharray="1,3"'}.get(key[2], "")
        path = " ".join(f"{_x(n):.1f},{_y(t):.1f}" for n, t in points)
        parts.append(f'<polyline points="{path}" fill="none" stroke="{colour}" '
                     f'stroke-width="2"{dash}/>')
        for n, t in points:
            parts.append(f'<circle cx="{_x(n):.1f}" cy="{_y(t):.1f}" r="3.5" fill="{colour}">'
                         f'<title>{_label(*key)}: {n} vehicles, {t:.2f} s</title></circle>')
        lx = x1 + 12
        parts.append(f'<line x1="{lx}" y1="{legend_y}" x2="{lx + 22}" y2="{legend_y}" '
                     f'stroke="{colour}" stroke-width="2"{dash}/>')
        label = _label(*key)
        if len(label) > 30:
            head, _, tail = label.rpartition(", ")
            parts.append(f'<text x="{lx + 28}" y="{legend_y + 4}">{head},</text>')
            legend_y += 14
            parts.append(f'<text x="{lx + 28}" y="{legend_y + 4}">{tail}</text>')
        else:
            parts.append(f'<text x="{lx + 28}" y="{legend_y + 4}">{label}</text>')
        legend_y += 22
    parts.append(f'<line x1="{x1 + 12}" y1="{legend_y}" x2="{x1 + 34}" y2="{legend_y}" '
                 'stroke="#d62728" stroke-width="3"/>')
    parts.append(f'<text x="{x1 + 40}" y="{legend_y + 4}">drone-show floor</text>')
    parts.append("</svg>")
    return "\n".join(parts) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reports", nargs="+", type=Path,
                        help="bench/planner.py or bench/prioritized.py JSON files")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/scaling.svg"))
    parser.add_argument("--note", default="", help="a line of text above the plot")
    args = parser.parse_args()
    reports = [json.loads(path.read_text()) for path in args.reports]
    lines = series(reports)
    if not lines:
        raise SystemExit("no families_summary (bench/planner.py) or prioritized gs/random "
                         "runs (bench/prioritized.py) in the given reports")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(render(lines, args.note))


if __name__ == "__main__":
    main()
