// @ts-check
// The editor's top view: the workspace, its obstacles with their clearance (the selected one
// with its resize handles), every vehicle's start (dot), goal (cross) and the line between,
// and the world point under a click.
import { $, $$, color, svgEl } from "./dom.js";
import { obstacleClearance, obstacleRows, readNumber, readObstacles, vehicleRows, workspace } from "./form.js";
import { drawObstacles } from "./obstacles.js";
import { byColour, layered } from "./scale.js";
import { editor } from "./state.js";

const SIZE = 400, PAD = 20;

function transform() {
  const { lo, hi } = workspace();
  const scale = (SIZE - 2 * PAD) / Math.max(hi[0] - lo[0], hi[1] - lo[1]);
  return {
    lo, hi, scale,
    /** @param {number} x @param {number} y */
    toSvg: (x, y) => [PAD + (x - lo[0]) * scale, SIZE - PAD - (y - lo[1]) * scale],
    /** @param {number} sx @param {number} sy */
    toWorld: (sx, sy) => [lo[0] + (sx - PAD) / scale, lo[1] + (SIZE - PAD - sy) / scale],
  };
}

/** Draw the form's vehicles; the selected one bold. */
export function drawTopView() {
  const view = $("#top-view");
  view.innerHTML = "";
  const tf = transform();
  const [x0, y0] = tf.toSvg(tf.lo[0], tf.lo[1]);
  const [x1, y1] = tf.toSvg(tf.hi[0], tf.hi[1]);
  svgEl("rect", { x: x0, y: y1, width: x1 - x0, height: y0 - y1, fill: "#fff", stroke: "#9aa4af" }, view);
  svgEl("text", { x: x0, y: y0 + 14, "font-size": 10, fill: "#6b7480" }, view).textContent =
    `(${tf.lo[0]}, ${tf.lo[1]})`;
  svgEl("text", { x: x1, y: y1 - 4, "font-size": 10, fill: "#6b7480", "text-anchor": "end" }, view)
    .textContent = `(${tf.hi[0]}, ${tf.hi[1]}) m`;
  const obstacles = readObstacles().map((ob, i) => ({ ob, i })).filter(({ ob }) => drawable(ob));
  const marked = new Set(obstacleRows().flatMap((tr, i) => (tr.classList.contains("has-error") ? [i] : [])));
  const layer = svgEl("g", { class: "obstacles" }, view);
  // A finger on an obstacle drags it, not the page: Chromium gives SVG shapes no touch-action
  // of their own, so the touch's default (scrolling) is cancelled. On this layer, not the view:
  // the press redraws the view, and the touch goes on at the shape first pressed, detached.
  for (const kind of ["touchstart", "touchmove"]) {
    layer.addEventListener(kind, (ev) => { if (ev.cancelable) ev.preventDefault(); }, { passive: false });
  }
  drawObstacles(layer, tf, obstacles.map(({ ob }) => ob), obstacleClearance(),
                { selected: obstacles.findIndex(({ i }) => i === editor.obstacle),
                  marked: new Set(obstacles.flatMap(({ i }, k) => (marked.has(i) ? [k] : []))),
                  handles: true });
  // Drawn indexes are the table's rows (some rows may be half typed and skipped).
  $$("g.obstacle", layer).forEach((g, k) => { g.setAttribute("data-index", String(obstacles[k].i)); });
  // Vehicles over the obstacles, not in the way of a press on them (see style.css).
  const marks = svgEl("g", { class: "vehicles" }, view);
  const rows = vehicleRows();
  if (layered(rows.length)) { drawLayers(marks, tf, rows); return; }
  rows.forEach((tr, i) => {
    const v = $$("input", tr).slice(1).map(readNumber).map(Number);  // empty reads 0
    const [sx, sy] = tf.toSvg(v[0], v[1]);
    const [gx, gy] = tf.toSvg(v[3], v[4]);
    if (![sx, sy, gx, gy].every(Number.isFinite)) return;
    const c = color(i), selected = i === editor.selected;
    svgEl("line", { x1: sx, y1: sy, x2: gx, y2: gy, stroke: c, "stroke-dasharray": "4 3", "stroke-width": selected ? 2 : 1 }, marks);
    svgEl("circle", { cx: sx, cy: sy, r: selected ? 6 : 4, fill: c }, marks);
    svgEl("path", { d: `M${gx - 5},${gy - 5}L${gx + 5},${gy + 5}M${gx - 5},${gy + 5}L${gx + 5},${gy - 5}`, stroke: c, "stroke-width": selected ? 3 : 2 }, marks);
    svgEl("text", { x: sx + 6, y: sy - 6, "font-size": 10, fill: c }, marks).textContent = $("input", tr).value;
  });
}

/** Whether every number an obstacle's drawing needs is there and finite.
 * @param {import("./obstacles.js").Obstacle} ob */
function drawable(ob) {
  const shape = /** @type {any} */ (ob.box ?? ob.cylinder ?? ob.prism);
  /** @param {any} v @returns {boolean} */
  const finite = (v) => (Array.isArray(v) ? v.every(finite) : v === undefined || (v !== null && Number.isFinite(v)));
  return Boolean(shape) && finite(Object.values(shape));
}

/** A show-sized form: per colour one path of start-goal lines and one of start dots, no
 * labels; the selected vehicle drawn on top as in a small fleet.
 * @param {Element} view @param {ReturnType<typeof transform>} tf
 * @param {HTMLTableRowElement[]} rows */
function drawLayers(view, tf, rows) {
  const moves = rows.map((tr, i) => {
    const v = $$("input", tr).slice(1).map(readNumber).map(Number);
    const [sx, sy] = tf.toSvg(v[0], v[1]).map((c) => Math.round(c * 10) / 10);
    const [gx, gy] = tf.toSvg(v[3], v[4]).map((c) => Math.round(c * 10) / 10);
    return { color: color(i), ok: [sx, sy, gx, gy].every(Number.isFinite), sx, sy, gx, gy };
  }).filter((m) => m.ok);
  for (const group of byColour(moves)) {
    svgEl("path", { d: group.map((m) => `M${m.sx},${m.sy}L${m.gx},${m.gy}`).join(""), stroke: group[0].color,
                    "stroke-width": 0.5, "stroke-opacity": 0.5, class: "move-lines" }, view);
    svgEl("path", { d: group.map((m) => `M${m.sx - 1.5},${m.sy}h3`).join(""), stroke: group[0].color,
                    "stroke-width": 3, class: "start-dots" }, view);
  }
}

/** The world point (x, y; m) under a click on the top view.
 * @param {MouseEvent} ev
 * @returns {number[]} */
export function worldAt(ev) {
  const box = $("#top-view").getBoundingClientRect();
  const sx = ((ev.clientX - box.left) / box.width) * SIZE;
  const sy = ((ev.clientY - box.top) / box.height) * SIZE;
  return transform().toWorld(sx, sy);
}
