// @ts-check
// The plan's figures: the verification and solver tables, the 3-D trajectories (with the
// planned-now and flown markers the fly screen moves), the separation, speed and thrust
// plots. plotly.js (3.5 MB) is loaded only when a plan is first shown, never before the
// editor is usable.
import { $, badge, color, fmt } from "./dom.js";
import { obstacleMesh } from "./obstacles.js";
import { views } from "./state.js";
import { PATH_POINTS, byColour, decimated, layered } from "./scale.js";
import { minSeparation } from "./tracks.js";

/** @typedef {import("./state.js").Plan} Plan */
/** @typedef {import("./state.js").Trajectory} Trajectory */

const PLOT_CONFIG = { responsive: true, displaylogo: false };
/** Top margin (px) of a captioned plot: plotly's toolbar (top right, ~25 px) in a row of its
 * own, the caption in the row under it. */
const CAPTIONED_TOP = 54;

/** A plot's caption, left-aligned just above its plotting area, under the toolbar's row
 * (centred at the top, the toolbar covered its end). @param {string} text */
const caption = (text) => ({
  text, font: { size: 13 }, x: 0, xref: "paper", xanchor: "left",
  y: 1, yref: "paper", yanchor: "bottom", pad: { b: 8 },
});
const PLOTLY_URL = "/vendor/plotly.min.js";

/** @type {Promise<any> | null} */
let plotlyLoading = null;

/** The Plotly global once loaded, else null. @returns {any} */
const plotly = () => /** @type {any} */ (window).Plotly ?? null;

/** plotly.js, loaded once on first use (a script element: it is not an ES module).
 * @returns {Promise<any>} */
export function loadPlotly() {
  if (plotly()) return Promise.resolve(plotly());
  plotlyLoading ??= new Promise((resolve, reject) => {
    const script = document.createElement("script");
    script.src = PLOTLY_URL;
    script.onload = () => resolve(plotly());
    script.onerror = () => { plotlyLoading = null; reject(new Error(`${PLOTLY_URL} did not load`)); };
    document.head.appendChild(script);
  });
  return plotlyLoading;
}

/** Draw every figure of a plan (plotly loaded first; without it the tables alone).
 * @param {Plan} plan
 * @param {boolean} planOk
 * @param {Trajectory} traj  10 Hz samples
 * @param {Trajectory} sepTraj  20 Hz samples */
export async function renderFigures(plan, planOk, traj, sepTraj) {
  // The tables wait for the plots too, so a plan appears whole.
  const Plotly = await loadPlotly().catch(() => null);
  renderSummary(plan, planOk);
  if (!Plotly) return;
  // One figure per task: a show-sized plan's figures never hold the page for their sum.
  for (const draw of [() => render3d(plan, traj), () => renderSeparation(plan, sepTraj),
                      () => renderSpeed(sepTraj), () => renderThrust(plan)]) {
    draw();
    await nextTask();
  }
}

/** A promise resolved in a later task, so the browser may draw and answer input between.
 * @returns {Promise<void>} */
export const nextTask = () => new Promise((resolve) => setTimeout(resolve, 0));

/** One line trace per vehicle; above LAYERED_ABOVE vehicles one per colour, each vehicle's
 * path decimated and separated from the next by a gap (null), its id as every point's hover
 * text; `meta.vehicles` says how many vehicles a trace carries.
 * @param {{id: string}[]} vehicles
 * @param {(v: any) => number[][]} pointsOf  a vehicle's points
 * @param {(i: number) => any} styleOf  the trace's style for vehicle i (the layer's first)
 * @param {boolean} [labelled]  layers carry hover text (ids); without it no hover at all
 * @returns {any[]} */
export function lineTraces(vehicles, pointsOf, styleOf, labelled = true) {
  if (!layered(vehicles.length)) {
    return vehicles.map((v, i) => ({ name: v.id, meta: { vehicles: 1 }, ...columns([pointsOf(v)]), ...styleOf(i) }));
  }
  const indexed = vehicles.map((_, i) => ({ i, color: color(i) }));
  return byColour(indexed).map((layer) => {
    const members = layer.map((m) => m.i);
    const parts = members.map((i) => {
      const points = pointsOf(vehicles[i]);
      return decimated(points.length, PATH_POINTS).map((k) => points[k]);
    });
    const hover = labelled
      ? { text: members.flatMap((i, j) => [...parts[j].map(() => vehicles[i].id), ""]), hoverinfo: "text" }
      : { hoverinfo: "skip" };
    return { name: `${members.length} vehicles`, meta: { vehicles: members.length },
             ...columns(parts), ...styleOf(members[0]), ...hover };
  });
}

/** x, y (and z when the points have it) columns of paths, null between two paths.
 * @param {number[][][]} paths @returns {Record<string, (number | null)[]>} */
function columns(paths) {
  const axes = paths[0] && paths[0][0] && paths[0][0].length > 2 ? ["x", "y", "z"] : ["x", "y"];
  /** @type {Record<string, (number | null)[]>} */
  const out = {};
  axes.forEach((axis, a) => {
    out[axis] = paths.length === 1 ? paths[0].map((p) => p[a])
      : paths.flatMap((path) => [...path.map((p) => p[a]), null]);
  });
  return out;
}

/** @param {Plan} plan @param {Trajectory} traj */
function render3d(plan, traj) {
  const many = traj.vehicles.length > 16;
  const lines = lineTraces(traj.vehicles, (v) => v.position, (i) => ({
    type: "scatter3d", mode: "lines", line: { color: color(i), width: 3 },
    hoverinfo: "name",
  }), false);  // in layers the "planned now" markers name the vehicles
  markers.lines = lines.length;
  const now = {
    type: "scatter3d", mode: "markers", name: "planned now", showlegend: false,
    x: [], y: [], z: [], text: traj.vehicles.map((v) => v.id), hoverinfo: "text",
    marker: { size: 4, color: traj.vehicles.map((_, i) => color(i)), opacity: 0.5 },
  };
  const flown = {
    type: "scatter3d", mode: "markers+text", name: "flown",
    x: [], y: [], z: [], text: [], hoverinfo: "text", textposition: "top center",
    marker: { size: 6, symbol: "diamond", color: [] },
  };
  const s = plan.scenario.limits;
  const layout = {
    margin: { l: 0, r: 0, t: CAPTIONED_TOP, b: 0 }, showlegend: !many,
    title: caption("trajectories (world frame, z up); rings: plan now, diamonds: flown"),
    scene: {
      aspectmode: "data",
      xaxis: { title: { text: "x (m)" }, range: [s.position_min[0], s.position_max[0]] },
      yaxis: { title: { text: "y (m)" }, range: [s.position_min[1], s.position_max[1]] },
      zaxis: { title: { text: "z (m)" }, range: [s.position_min[2], s.position_max[2]] },
    },
    uirevision: "keep",
  };
  const solids = obstacleMesh(plan.scenario.obstacles ?? []);  // after the markers: their indexes hold
  plotly().react("plot3d", [...lines, now, flown, ...(solids ? [solids] : [])], layout, PLOT_CONFIG);
}

/** The 3-D view's moving markers: their data changes at once, the WebGL scene is redrawn
 * once per frame at most and only while the view is on screen (an off-screen redraw costs a
 * laptop CPU for nothing; it is drawn as it scrolls into view), and at show scale not while
 * the plan plays (a redraw rebuilds every path of the scene: 0.8-1.6 s at 1,000 vehicles in
 * software WebGL, a frame held that long at every played sample; the fly view plays, the
 * 3-D view is drawn where playing stops). */
const markers = { lines: 0, scheduled: false, onScreen: true, watched: false };

/** Whether the plan plays (▶) on a fleet drawn in layers. */
const playingAtScale = () => Boolean(views.playTimer && views.traj
  && layered(views.traj.vehicles.length));

/** @returns {any} the 3-D view's element (its `data` once plotted) */
const scene = () => /** @type {any} */ ($("#plot3d"));

/** Redraw the markers in the next frame, if the view is on screen. */
function scheduleMarkers() {
  if (!markers.watched && typeof IntersectionObserver !== "undefined") {
    markers.watched = true;
    new IntersectionObserver((entries) => {
      markers.onScreen = entries.some((e) => e.isIntersecting);
      scheduleMarkers();
    }).observe(scene());
  }
  if (markers.scheduled || !markers.onScreen || playingAtScale()) return;
  markers.scheduled = true;
  requestAnimationFrame(() => {
    markers.scheduled = false;
    const data = scene().data;
    if (!markers.onScreen || !data || !data[markers.lines + 1]) return;
    const traces = [data[markers.lines], data[markers.lines + 1]];
    plotly().restyle("plot3d", {  // both traces in one redraw
      x: traces.map((t) => t.x.slice()), y: traces.map((t) => t.y.slice()),
      z: traces.map((t) => t.z.slice()), text: traces.map((t) => t.text.slice()),
      "marker.color": traces.map((t) => t.marker.color.slice()),
    }, [markers.lines, markers.lines + 1]);
  });
}

/** Move the 3-D view's "planned now" markers (the trace after the vehicles' lines), each in
 * its colour at that time (a show's lights).
 * @param {number[][]} positions @param {string[]} colours */
export function showPlannedNow(positions, colours) {
  const trace = scene().data?.[markers.lines];
  if (!trace) return;
  [trace.x, trace.y, trace.z] = [0, 1, 2].map((a) => positions.map((p) => p[a]));
  trace.marker.color = colours;
  scheduleMarkers();
}

/** Move the 3-D view's "flown" markers (the last trace), labelled with the vehicles' ids.
 * @param {{id: string, color: string, position: number[]}[]} shown */
export function showFlown(shown) {
  const trace = scene().data?.[markers.lines + 1];
  if (!trace) return;
  [trace.x, trace.y, trace.z] = [0, 1, 2].map((a) => shown.map((v) => v.position[a]));
  trace.text = shown.map((v) => v.id);
  trace.marker.color = shown.map((v) => v.color);
  scheduleMarkers();
}

/** @param {HTMLTableElement} table @param {string} label @param {string} value
 * @param {boolean} [good] */
function row(table, label, value, good) {
  const tr = document.createElement("tr");
  const a = document.createElement("td"), b = document.createElement("td");
  a.textContent = label;
  if (good === undefined) b.textContent = value; else b.append(badge(good, value));
  tr.append(a, b);
  table.appendChild(tr);
  return b;
}

/** The method that planned, and what became of the others that ran (auto races two).
 * @param {Plan} plan
 * @returns {string} */
function methodText(plan) {
  const others = (plan.attempts || []).filter((a) => a.outcome === "failed" || a.outcome === "cancelled")
    .map((a) => `${a.method} ${a.outcome} after ${fmt(a.seconds, 2)} s`);
  return String(plan.method) + (others.length ? ` (${others.join("; ")})` : "");
}

/** @param {Plan} plan @param {boolean} planOk */
function renderSummary(plan, planOk) {
  const v = plan.verification || {};
  const R = plan.scenario.min_separation;
  const ver = $("#verification");
  ver.innerHTML = "<caption>verification</caption>";
  row(ver, "status", `${plan.status}${plan.message ? ": " + plan.message : ""}`, planOk);
  const cell = row(ver, "min separation (continuous)", `${fmt(v.min_separation_continuous)} m (R = ${R} m)`, v.separated);
  cell.id = "min-separation-value";
  cell.dataset.value = v.min_separation_continuous;
  if (v.closest_pair && v.closest_pair.length) row(ver, "closest pair", `${v.closest_pair.join(" – ")} at t = ${fmt(v.closest_time, 2)} s`);
  row(ver, "within bounds", v.within_bounds ? "yes" : "no", v.within_bounds);
  row(ver, "flyable", v.flyable ? "yes" : "no", v.flyable);
  row(ver, "thrust range", v.thrust_range ? `${fmt(v.thrust_range[0], 3)} – ${fmt(v.thrust_range[1], 3)} m/s²` : "–");
  row(ver, "body-rate peak", `${fmt(v.body_rate_peak, 2)} rad/s`);
  /** @type {[string, number][]} */
  const excess = Object.entries(v.max_violation || {});
  const worst = excess.sort((a, b) => (b[1] ?? 0) - (a[1] ?? 0))[0];
  if (worst) row(ver, "largest bound excess", `${worst[0]}: ${fmt(worst[1], 6)}`);
  const sol = $("#solver-figures");
  sol.innerHTML = "<caption>solver</caption>";
  const its = plan.iterations || [];
  const method = row(sol, "method", plan.method ? methodText(plan) : "–");
  method.id = "plan-method";
  row(sol, "solver", String(plan.solver));
  row(sol, "SCP iterations", its.length ? String(its[its.length - 1].iteration) : "–");
  const cost = row(sol, "final cost", plan.vehicles.length ? fmt(planCost(plan), 2) : "–");
  cost.id = "final-cost";
  row(sol, "QP solves", String(its.reduce((s, r) => s + r.qp_solves, 0)));
  row(sol, "separation rows (last)", its.length ? String(its[its.length - 1].separation_rows) : "–");
  row(sol, "planning time", `${fmt(plan.timing.total_s, 3)} s`);
  row(sol, "first QP", `${fmt(plan.timing.first_qp_s, 3)} s`);
  row(sol, "vehicles × steps", `${plan.vehicles.length} × ${plan.scenario.steps} (dt ${plan.scenario.dt} s)`
    + (plan.horizon ? ", steps chosen by the planner" : ""));
}

/** The plan's total-thrust cost sum ||a + g||² over every vehicle and step (Plan.cost), from
 * its thrust ||a + g||: with prioritized batches the last iteration's cost is only the last
 * batch's.
 * @param {Plan} plan @returns {number} */
export function planCost(plan) {
  return plan.vehicles.reduce((sum, v) => sum + v.thrust.reduce((s, f) => s + f * f, 0), 0);
}

/** The separation plot: the plan's minimum pairwise distance against R, and the measured
 * one of the flight replayed (views.measured) when there is one.
 * @param {Plan} plan
 * @param {Trajectory} traj */
export function renderSeparation(plan, traj) {
  const Plotly = plotly();
  if (!Plotly) return;
  const R = plan.scenario.min_separation;
  if (traj.vehicles.length < 2) { Plotly.purge("separation-plot"); return; }
  const sep = minSeparation(plan, traj);
  views.sep = sep;
  const low = Math.min(...sep.d);
  /** @type {any[]} */
  const traces = [
    { x: sep.t, y: sep.d, mode: "lines", name: "min pairwise distance", line: { color: "#1f6feb" } },
    { x: [0, traj.t[traj.t.length - 1]], y: [R, R], mode: "lines", name: `R = ${R} m`, line: { color: "#c62828", dash: "dash" } },
  ];
  if (views.measured) {
    traces.push({ x: views.measured.t, y: views.measured.d, mode: "lines", name: views.measured.label,
                  line: { color: "#2e7d32" } });
  }
  Plotly.react("separation-plot", traces, {
    title: caption(`minimum pairwise separation: ${low.toFixed(3)} m (R = ${R} m)`),
    margin: { l: 50, r: 10, t: CAPTIONED_TOP, b: 40 }, xaxis: { title: { text: "t (s)" } },
    yaxis: { title: { text: "m" }, rangemode: "tozero" }, legend: { orientation: "h" },
  }, PLOT_CONFIG);
  $("#separation-plot").dataset.minimum = low;
}

/** @param {Trajectory} traj */
function renderSpeed(traj) {
  const speeds = lineTraces(traj.vehicles,
    (v) => v.velocity.map((u, k) => [traj.t[k], Math.hypot(u[0], u[1], u[2])]),
    (i) => ({ mode: "lines", line: { color: color(i), width: 1 } }), false);
  plotly().react("speed-plot", speeds, {
    title: caption("speed per vehicle"), showlegend: false,
    margin: { l: 50, r: 10, t: CAPTIONED_TOP, b: 40 }, xaxis: { title: { text: "t (s)" } }, yaxis: { title: { text: "m/s" } },
  }, PLOT_CONFIG);
}

/** @param {Plan} plan */
function renderThrust(plan) {
  const lim = plan.scenario.limits;
  const end = plan.scenario.steps * plan.scenario.dt;
  /** @type {any[]} */
  const traces = lineTraces(plan.vehicles, (v) => v.thrust.map((f, k) => [v.t[k], f]),
    (i) => ({ mode: "lines", line: { color: color(i), width: 1, shape: "hv" } }), false);
  for (const [key, label] of [["thrust_min", "min"], ["thrust_max", "max"]]) {
    if (lim[key] !== undefined) traces.push({ x: [0, end], y: [lim[key], lim[key]], mode: "lines", name: `thrust ${label}`, line: { color: "#c62828", dash: "dot" } });
  }
  plotly().react("thrust-plot", traces, {
    title: caption("mass-normalised thrust per vehicle"), showlegend: false,
    margin: { l: 50, r: 10, t: CAPTIONED_TOP, b: 40 }, xaxis: { title: { text: "t (s)" } }, yaxis: { title: { text: "m/s²" } },
  }, PLOT_CONFIG);
}
