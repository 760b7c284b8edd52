// @ts-check
// Obstacles as the page draws them: each kind's footprint and clearance outline on a top-down
// SVG view (editor and fly view), and one mesh trace of all of them for the 3-D plan.
// Shapes are the scenario contract's: box {min, max}, cylinder {center, radius, z}, prism
// {polygon, z}.
import { svgEl } from "./dom.js";

/** @typedef {{id: string, box?: {min: number[], max: number[]},
 *   cylinder?: {center: number[], radius: number, z: number[]},
 *   prism?: {polygon: number[][], z: number[]}}} Obstacle */
/** @typedef {{toSvg: (x: number, y: number) => number[], scale: number}} Transform */

const SIDES = 32;  // a cylinder's facets in the 3-D mesh

/** The kind of an obstacle: "box", "cylinder" or "prism" (null for none of them).
 * @param {Obstacle} ob @returns {"box" | "cylinder" | "prism" | null} */
export const kindOf = (ob) => (ob.box ? "box" : ob.cylinder ? "cylinder" : ob.prism ? "prism" : null);

/** The footprint polygon (x, y; m) of a box or prism, counter-clockwise.
 * @param {Obstacle} ob @returns {number[][]} */
function polygonOf(ob) {
  if (ob.box) {
    const [a, b] = [ob.box.min, ob.box.max];
    return [[a[0], a[1]], [b[0], a[1]], [b[0], b[1]], [a[0], b[1]]];
  }
  return ob.prism ? ob.prism.polygon : [];
}

/** Every vertex moved `c` metres outward along its corner's bisector (a mitred offset of a
 * counter-clockwise convex polygon: the clearance outline, slightly wide at sharp corners).
 * @param {number[][]} poly @param {number} c @returns {number[][]} */
function offsetPolygon(poly, c) {
  const n = poly.length;
  let area = 0;
  for (let i = 0; i < n; i++) area += poly[i][0] * poly[(i + 1) % n][1] - poly[(i + 1) % n][0] * poly[i][1];
  const sign = area >= 0 ? 1 : -1;  // clockwise polygons offset outward too
  return poly.map((p, i) => {
    const prev = poly[(i + n - 1) % n], next = poly[(i + 1) % n];
    /** @param {number[]} a @param {number[]} b */
    const normal = (a, b) => { const dx = b[0] - a[0], dy = b[1] - a[1], l = Math.hypot(dx, dy) || 1; return [sign * dy / l, -sign * dx / l]; };
    const n1 = normal(prev, p), n2 = normal(p, next);
    const bx = n1[0] + n2[0], by = n1[1] + n2[1];
    const dot = (bx * n1[0] + by * n1[1]) || 1;
    return [p[0] + c * bx / dot, p[1] + c * by / dot];
  });
}

/** @param {Transform} tf @param {number[][]} poly */
const points = (tf, poly) => poly.map(([x, y]) => tf.toSvg(x, y).map((v) => v.toFixed(1)).join(",")).join(" ");

/** Draw obstacles on a top-down view: the solid filled grey, its clearance a dashed outline.
 * Each drawing is a `g.obstacle` with `data-index` and `data-id`; `marked` indexes are drawn
 * red (an error names them), `selected` bold and, with `handles`, with its resize handles.
 * @param {Element} parent @param {Transform} tf @param {Obstacle[]} obstacles
 * @param {number} clearance
 * @param {{selected?: number, marked?: Set<number>, handles?: boolean}} [opts] */
export function drawObstacles(parent, tf, obstacles, clearance, opts = {}) {
  obstacles.forEach((ob, i) => {
    const marked = opts.marked ? opts.marked.has(i) : false;
    const stroke = marked ? "#c62828" : "#4a5560";
    const g = svgEl("g", { class: `obstacle${marked ? " invalid" : ""}${i === opts.selected ? " selected" : ""}`,
                           "data-index": i, "data-id": ob.id, "data-kind": kindOf(ob) ?? "" }, parent);
    const width = i === opts.selected ? 2.5 : 1;
    const solid = { fill: marked ? "#f4c7c7" : "#c9cfd6", stroke, "stroke-width": width, class: "solid" };
    const dashed = { fill: "none", stroke, "stroke-dasharray": "4 3", "stroke-width": 1, class: "clearance" };
    if (ob.cylinder) {
      const [cx, cy] = tf.toSvg(ob.cylinder.center[0], ob.cylinder.center[1]);
      svgEl("circle", { cx, cy, r: ob.cylinder.radius * tf.scale, ...solid }, g);
      svgEl("circle", { cx, cy, r: (ob.cylinder.radius + clearance) * tf.scale, ...dashed }, g);
    } else if (ob.box) {
      const [x0, y0] = tf.toSvg(ob.box.min[0], ob.box.min[1]);
      const [x1, y1] = tf.toSvg(ob.box.max[0], ob.box.max[1]);
      const x = Math.min(x0, x1), y = Math.min(y0, y1), w = Math.abs(x1 - x0), h = Math.abs(y1 - y0);
      const c = clearance * tf.scale;  // a box grown by c: the rectangle with corners of radius c
      svgEl("rect", { x, y, width: w, height: h, ...solid }, g);
      svgEl("rect", { x: x - c, y: y - c, width: w + 2 * c, height: h + 2 * c, rx: c, ry: c, ...dashed }, g);
    } else if (ob.prism) {
      const poly = polygonOf(ob);
      svgEl("polygon", { points: points(tf, poly), ...solid }, g);
      svgEl("polygon", { points: points(tf, offsetPolygon(poly, clearance)), ...dashed }, g);
    }
    if (opts.handles && i === opts.selected) drawHandles(g, tf, ob);
    svgEl("title", {}, g).textContent = `obstacle ${ob.id}`;
  });
}

/** A box's handles on its four corners (`data-handle` "min,max": the corner at min x, max y)
 * and a cylinder's on its rim, east of its centre ("radius"); a prism has none. Each is a
 * `g.handle`: a small square inside a wider transparent disc a finger can hit, the disc kept
 * small enough on a small obstacle to leave its middle free for moving it.
 * @param {Element} g @param {Transform} tf @param {Obstacle} ob */
function drawHandles(g, tf, ob) {
  /** @type {[string, number[], string][]} handle, world point, cursor */
  const handles = [];
  let size = 0;  // svg units from a handle to the obstacle's middle, about
  if (ob.box) {
    const { min, max } = ob.box;
    for (const [xe, ye, cursor] of [["min", "min", "nesw"], ["max", "min", "nwse"], ["max", "max", "nesw"], ["min", "max", "nwse"]]) {
      handles.push([`${xe},${ye}`, [(xe === "min" ? min : max)[0], (ye === "min" ? min : max)[1]], `${cursor}-resize`]);
    }
    size = Math.min(Math.abs(max[0] - min[0]), Math.abs(max[1] - min[1])) * tf.scale / 2;
  } else if (ob.cylinder) {
    const { center: c, radius: r } = ob.cylinder;
    handles.push(["radius", [c[0] + r, c[1]], "ew-resize"]);
    size = Math.abs(r) * tf.scale;
  }
  const hit = Math.min(12, Math.max(5, size / 2));
  for (const [name, [x, y], cursor] of handles) {
    const [sx, sy] = tf.toSvg(x, y);
    const h = svgEl("g", { class: "handle", "data-handle": name, style: `cursor: ${cursor}` }, g);
    svgEl("circle", { cx: sx, cy: sy, r: hit, fill: "transparent" }, h);
    svgEl("rect", { x: sx - 4, y: sy - 4, width: 8, height: 8, fill: "#fff", stroke: "#1f6feb", "stroke-width": 1.5 }, h);
  }
}

/** All obstacles as one Plotly mesh3d trace (boxes and prisms as their polygons extruded,
 * cylinders as 32-sided prisms), or null when there are none.
 * @param {Obstacle[]} obstacles @returns {any} */
export function obstacleMesh(obstacles) {
  /** @type {number[]} */ const x = [], y = [], z = [], i = [], j = [], k = [];
  for (const ob of obstacles) {
    let poly, z0, z1;
    if (ob.cylinder) {
      const { center: c, radius: r } = ob.cylinder;
      poly = Array.from({ length: SIDES }, (_, s) => [c[0] + r * Math.cos(2 * Math.PI * s / SIDES), c[1] + r * Math.sin(2 * Math.PI * s / SIDES)]);
      [z0, z1] = ob.cylinder.z;
    } else if (ob.box) { poly = polygonOf(ob); z0 = ob.box.min[2]; z1 = ob.box.max[2]; }
    else if (ob.prism) { poly = ob.prism.polygon; [z0, z1] = ob.prism.z; }
    else continue;
    const base = x.length, n = poly.length;
    for (const zz of [z0, z1]) for (const p of poly) { x.push(p[0]); y.push(p[1]); z.push(zz); }
    for (let s = 0; s < n; s++) {  // the sides: two triangles each
      const a = base + s, b = base + (s + 1) % n;
      i.push(a, b); j.push(b, b + n); k.push(a + n, a + n);
    }
    for (let s = 1; s < n - 1; s++) {  // the caps: fans (the prisms are convex)
      i.push(base, base + n); j.push(base + s, base + n + s); k.push(base + s + 1, base + n + s + 1);
    }
  }
  if (x.length === 0) return null;
  return { type: "mesh3d", name: "obstacles", x, y, z, i, j, k, color: "#8a939d", opacity: 0.45,
           flatshading: true, hoverinfo: "name", showlegend: false };
}
