"""A plan's validation report: one self-contained HTML file a crew can keep, send or print.

It holds, against the plan's limits: a verdict per check (the continuous-time verification
with its tolerances, and each figure of `gcs.show.metrics` for every drone); a table of the
worst moments (time, drones, value, limit); one chart per figure over time with the fleet's
envelope (the worst value over all drones at each step) and the worst drones' own curves
(`WORST_DRONES`), so a 1,000-drone show stays a few megabytes; each drone's worst values with
its verdict; the light programs as one colour strip per drone (a sequence with colours); and
the plan's method, horizon and planning time. Charts are plotly's, whose JavaScript is
written into the file: it opens offline and asks the network for nothing.
"""

from __future__ import annotations

import base64
import html
import io
import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from gcs.export.lightcode import colors_at
from gcs.export.lights import light_changes
from gcs.show.metrics import Metric, metrics
from planner.result import Plan
from planner.verification.ground import starts_on_the_ground
from planner.verification.verify import BOUND_TOLERANCE, SEPARATION_TOLERANCE, verify

__all__ = ["WORST_DRONES", "report_html"]

#: Drones drawn on their own in each chart (the worst ones by that figure).
WORST_DRONES = 3
#: Columns of the light strips (samples over the show).
LIGHT_SAMPLES = 400

_STYLE = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}
h1{margin-bottom:0}.meta{color:#555}
table{border-collapse:collapse;margin:0.5em 0 1.5em}
td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#f3f3f3}
td.l,th.l{text-align:left}.pass{color:#176f2c;font-weight:600}.fail{color:#b00020;
font-weight:600}.chart{height:320px}details{margin:1em 0}
img.lights{image-rendering:pixelated;width:100%;height:auto;border:1px solid #ccc}
"""


def _verdict(ok: bool) -> str:
    return '<span class="pass">pass</span>' if ok else '<span class="fail">FAIL</span>'


def _num(x: float | None, digits: int = 3) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def _chart(metric: Metric, ids: Sequence[str], index: int) -> str:
    """A plotly chart: the fleet's envelope, the worst drones, the limit lines."""
    import plotly.graph_objects as go
    import plotly.io as pio

    values = np.where(np.isfinite(metric.values), metric.values, np.nan)
    worst = metric.worst_per_drone()
    order = np.argsort(worst if metric.low else -worst)[:WORST_DRONES]
    times = metric.times.round(3).tolist()
    figure = go.Figure()
    with warnings.catch_warnings():  # a step with no drone in the air has no distance
        warnings.simplefilter("ignore", RuntimeWarning)
        envelope = np.nanmin(values, axis=0) if metric.low else np.nanmax(values, axis=0)
    figure.add_scatter(x=times, y=np.round(envelope, 4).tolist(), name="fleet (worst drone)",
                       line={"color": "#444", "width": 3})
    if metric.floor is not None:
        lowest = np.nanmin(values, axis=0)
        figure.add_scatter(x=times, y=np.round(lowest, 4).tolist(), name="fleet (lowest)",
                           line={"color": "#888", "width": 2})
    for n in order.tolist():
        if math.isfinite(worst[n]):
            figure.add_scatter(x=times, y=np.round(values[n], 4).tolist(), name=ids[n],
                               line={"width": 1})
    for bound, label in ((metric.limit, "limit"), (metric.floor, "floor")):
        if bound is not None:
            figure.add_hline(y=bound, line={"color": "#b00020", "dash": "dash"},
                             annotation_text=f"{label} {bound:g} {metric.unit}")
    figure.update_layout(title=f"{metric.title} ({metric.unit})", xaxis_title="time (s)",
                         margin={"l": 50, "r": 20, "t": 40, "b": 40}, height=320)
    return str(pio.to_html(figure, include_plotlyjs=False, full_html=False,
                           div_id=f"chart-{index}"))


def _moment(metric: Metric, ids: Sequence[str]) -> tuple[str, str, str, str]:
    """(time, drone(s), value, limit) of the metric's worst moment."""
    values = np.where(np.isfinite(metric.values), metric.values,
                      np.inf if metric.low else -np.inf)
    flat = int(np.argmin(values) if metric.low else np.argmax(values))
    n, k = divmod(flat, values.shape[1])
    value = float(values[n, k])
    who = ids[n]
    if metric.key == "distance" and math.isfinite(value):
        others = [m for m in range(len(ids)) if m != n
                  and math.isclose(values[m, k], value, rel_tol=1e-9, abs_tol=1e-9)]
        if others:
            who = f"{ids[n]}, {ids[others[0]]}"
    bound = metric.limit if metric.limit is not None else metric.floor
    return (f"{metric.times[k]:.2f}", who, _num(value), "—" if bound is None else f"{bound:.4g}")


def _lights_png(plan: Plan) -> str | None:
    """The light programs as a PNG (one row per drone, time left to right), base64; None
    for a plan without lights."""
    from PIL import Image

    horizon = plan.scenario.horizon
    times = np.linspace(0.0, horizon, LIGHT_SAMPLES)
    rows = []
    for track in plan.vehicles:
        changes = light_changes(plan, track.id)
        if changes is None:
            return None
        rows.append(colors_at(changes, times))
    pixels = np.clip(np.rint(np.array(rows)), 0, 255).astype(np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(pixels, "RGB").save(buffer, format="PNG", optimize=True)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def report_html(plan: Plan, *, title: str | None = None) -> tuple[str, bool]:
    """The report's HTML and whether every check passes."""
    from plotly.offline import get_plotlyjs

    scenario = plan.scenario
    ids = list(scenario.ids)
    ground = starts_on_the_ground(plan.sequence)
    check = verify(scenario, plan.positions(), plan.velocities(), plan.accelerations(),
                   ground=ground)
    figures = metrics(plan)
    tolerance = BOUND_TOLERANCE
    per_drone = {m.key: m.passes(SEPARATION_TOLERANCE if m.key == "distance" else tolerance)
                 for m in figures}
    rows = [("Continuous-time verification", check.verified,
             "; ".join(check.failures()) or
             f"separation ≥ R − {check.separation_tolerance:g} m over continuous time "
             f"(closest {_num(check.min_separation_continuous, 4)} m: "
             f"{', '.join(check.closest_pair) or '—'} at {check.closest_time:.2f} s); every "
             f"box and boundary within {check.bound_tolerance:g}; thrust and body rates "
             f"within limits" + ("; pairs on the ground not counted" if ground else ""))]
    for m in figures:
        failing = [ids[n] for n in np.flatnonzero(~per_drone[m.key])]
        rows.append((m.title, not failing,
                     "every drone within the limit" if not failing else
                     f"{len(failing)} drone(s): {', '.join(failing[:10])}"
                     + (" …" if len(failing) > 10 else "")))
    passed = all(ok for _, ok, _ in rows)
    name = title or scenario.name
    out = [f"<!doctype html><html><head><meta charset='utf-8'><title>"
           f"{html.escape(name)}: validation report</title><style>{_STYLE}</style>"
           f"<script>{get_plotlyjs()}</script></head><body>",
           f"<h1>{html.escape(name)}: validation report</h1>",
           f"<p class='meta'>{len(ids)} drones, {scenario.horizon:g} s (dt {scenario.dt:g} s), "
           f"status {html.escape(plan.status)}, method {html.escape(plan.method or '—')}, "
           f"planning time {float(plan.timing.get('total_s', 0.0)):.1f} s; R = "
           f"{scenario.min_separation:g} m"
           + (", takes off from and lands on the ground" if ground else "")
           + f". Verdict: {_verdict(passed)}</p>",
           "<h2>Checks</h2><table><tr><th class='l'>check</th><th>verdict</th>"
           "<th class='l'>detail</th></tr>"]
    out += [f"<tr><td class='l'>{html.escape(label)}</td><td>{_verdict(ok)}</td>"
            f"<td class='l'>{html.escape(detail)}</td></tr>" for label, ok, detail in rows]
    out.append("</table><h2>Worst moments</h2><table><tr><th class='l'>figure</th>"
               "<th>time (s)</th><th class='l'>drones</th><th>value</th><th>limit</th></tr>")
    for m in figures:
        t, who, value, bound = _moment(m, ids)
        out.append(f"<tr><td class='l'>{html.escape(m.title)} ({m.unit})</td><td>{t}</td>"
                   f"<td class='l'>{html.escape(who)}</td><td>{value}</td><td>{bound}</td></tr>")
    out.append("</table><h2>Over time</h2><p class='meta'>Each chart: the fleet's worst value "
               f"at each step, and the {WORST_DRONES} worst drones' own curves; the dashed "
               "line is the limit.</p>")
    out += [f"<div class='chart'>{_chart(m, ids, i)}</div>" for i, m in enumerate(figures)]
    strip = _lights_png(plan)
    if strip is not None:
        out.append(f"<h2>Lights</h2><p class='meta'>One row per drone (in plan order), time "
                   f"left to right over {scenario.horizon:g} s.</p><img class='lights' "
                   f"alt='light programs' src='data:image/png;base64,{strip}'>")
    out.append("<h2>Per drone</h2><details><summary>each drone's worst values</summary>"
               "<table><tr><th class='l'>drone</th>"
               + "".join(f"<th>{html.escape(m.title)} ({m.unit})</th>" for m in figures)
               + "<th>verdict</th></tr>")
    worst = {m.key: m.worst_per_drone() for m in figures}
    for n, vid in enumerate(ids):
        ok = all(bool(per_drone[m.key][n]) for m in figures)
        out.append(f"<tr><td class='l'>{html.escape(vid)}</td>"
                   + "".join(f"<td>{_num(float(worst[m.key][n]))}</td>" for m in figures)
                   + f"<td>{_verdict(ok)}</td></tr>")
    out.append("</table></details></body></html>")
    return "".join(out), passed


def report_facts(plan: Plan) -> dict[str, Any]:
    """The figures the report states, for scripts and tests: per metric its worst value
    and limit."""
    out: dict[str, Any] = {}
    for m in metrics(plan):
        worst = m.worst_per_drone()
        value = float(worst.min() if m.low else worst.max())
        out[m.key] = {"worst": value, "limit": m.limit}
    return out
