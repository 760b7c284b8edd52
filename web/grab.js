// @ts-check
// What a grab of an obstacle on the editor's top view drives: the fields of its table row a
// move or a resize handle changes, by how much for a pointer displacement, and within which
// bounds (a box keeps min < max by at least MIN_SIZE and stays in the workspace; a
// cylinder's radius stays positive and its circle in the workspace). No drawing, no events.
import { $$, clamp } from "./dom.js";
import { round2 } from "./presets.js";

/** The smallest box side and cylinder diameter a resize handle leaves (m). */
export const MIN_SIZE = 0.1;

/** One field a drag drives: its value at the grab, how far the pointer's path from `start`
 * to `at` moves it (m), and the bounds it is clamped to.
 * @typedef {{input: HTMLInputElement, at: number, lo: number, hi: number,
 *   delta: (start: number[], at: number[]) => number}} Grabbed */

/** A prism's polygon at the grab: it moves with the pointer (it has no fields).
 * @typedef {{tr: HTMLTableRowElement, at: number[][]}} GrabbedPolygon */

/** @param {number} axis */
const along = (axis) => (/** @type {number[]} */ s, /** @type {number[]} */ p) => p[axis] - s[axis];

/** The row's input at a field path ("min[0]", "radius").
 * @param {HTMLTableRowElement} tr @param {string} path @returns {HTMLInputElement | undefined} */
const field = (tr, path) => $$("input[data-path]", tr).find((i) => i.dataset.path === path);

/** The bounds a field is clamped to, widened to hold the value it had at the grab (a field
 * already beyond a bound does not jump at the first move, and only comes back toward it).
 * @param {number} at @param {number} lo @param {number} hi */
const bounds = (at, lo, hi) => ({ lo: Math.min(lo, at), hi: Math.max(hi, at) });

/** Moving an obstacle: every x and y field (box corners, cylinder centre) follows the
 * pointer, unbounded as typing is; a prism's polygon moves with them.
 * @param {HTMLTableRowElement} tr
 * @returns {{fields: Grabbed[], polygon: GrabbedPolygon | null}} */
export function grabMove(tr) {
  // x fields end in "[0]", y fields in "[1]" (min, max, center; z is "z[...]" or "[2]").
  const fields = $$("input[data-path]", tr).flatMap((input) => {
    const m = /^(min|max|center)\[([01])\]$/.exec(input.dataset.path || "");
    return m ? [{ input, at: Number(input.value), lo: -Infinity, hi: Infinity, delta: along(Number(m[2])) }] : [];
  });
  const polygon = tr.dataset.kind === "prism" ? { tr, at: JSON.parse(tr.dataset.polygon || "[]") } : null;
  return { fields, polygon };
}

/** Resizing by a handle (`data-handle` of obstacles.js): a box corner "min,max" drives min x
 * and max y; "radius" drives a cylinder's radius by the change in the pointer's distance from
 * its centre. Empty when the row has no such fields or they do not read as numbers.
 * @param {HTMLTableRowElement} tr @param {string} handle
 * @param {{lo: number[], hi: number[]}} ws the workspace
 * @returns {Grabbed[]} */
export function grabHandle(tr, handle, ws) {
  if (tr.dataset.kind === "box") {
    const ends = handle.split(",");
    return ends.flatMap((end, axis) => {
      const input = field(tr, `${end}[${axis}]`), other = field(tr, `${end === "min" ? "max" : "min"}[${axis}]`);
      if (!input || !other || !["min", "max"].includes(end)) return [];
      const at = Number(input.value), opposite = Number(other.value);
      if (!Number.isFinite(at) || !Number.isFinite(opposite)) return [];
      const range = end === "min" ? bounds(at, ws.lo[axis], opposite - MIN_SIZE)
        : bounds(at, opposite + MIN_SIZE, ws.hi[axis]);
      return [{ input, at, ...range, delta: along(axis) }];
    });
  }
  if (tr.dataset.kind === "cylinder" && handle === "radius") {
    const input = field(tr, "radius");
    const c = [0, 1].map((a) => Number(field(tr, `center[${a}]`)?.value));
    if (!input || !c.every(Number.isFinite) || !Number.isFinite(Number(input.value))) return [];
    const at = Number(input.value);
    // The circle stays within the workspace's sides (at least MIN_SIZE across).
    const room = Math.min(c[0] - ws.lo[0], ws.hi[0] - c[0], c[1] - ws.lo[1], ws.hi[1] - c[1]);
    /** @param {number[]} p */
    const from = (p) => Math.hypot(p[0] - c[0], p[1] - c[1]);
    return [{ input, at, ...bounds(at, MIN_SIZE / 2, Math.max(room, MIN_SIZE / 2)),
              delta: (s, p) => from(p) - from(s) }];
  }
  return [];
}

/** The value a grabbed field takes with the pointer at `at`: to the centimetre, in bounds.
 * @param {Grabbed} f @param {number[]} start @param {number[]} at @returns {number} */
export const valueAt = (f, start, at) => clamp(round2(f.at + f.delta(start, at)), f.lo, f.hi);

/** A grabbed polygon moved by the pointer's displacement (to the centimetre).
 * @param {GrabbedPolygon} g @param {number[]} start @param {number[]} at @returns {number[][]} */
export const polygonAt = (g, start, at) =>
  g.at.map(([x, y]) => [round2(x + at[0] - start[0]), round2(y + at[1] - start[1])]);
