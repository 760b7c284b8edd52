// @ts-check
// The top-down fly view: planned paths, where each vehicle should be at the slider's time,
// where it is (live or replayed) with a label (id, altitude) and its trail, a scale bar and,
// when the fleet has a geodetic origin, latitude/longitude at the corners. No map tiles: the
// page works offline. Pure drawing: no fetches, no page state.
import { svgEl } from "./dom.js";
import { drawObstacles } from "./obstacles.js";
import { PATH_POINTS, byColour, decimated, layered } from "./scale.js";

/** @typedef {{lat: number, lon: number}} LatLon */
/** @typedef {{lo: number[], hi: number[], scale: number,
 *   toSvg: (x: number, y: number) => number[],
 *   toWorld: (sx: number, sy: number) => number[]}} ViewTransform */
/** @typedef {{id: string, color: string, position?: number[] | null, velocity?: number[],
 *   trail?: number[][], alert?: boolean}} MovingVehicle */

export const VIEW = 400;  // viewBox size (square)

/** World (x east, y north; m) <-> viewBox coordinates for the workspace box [lo, hi].
 * @param {number[]} lo
 * @param {number[]} hi
 * @param {number} [pad]
 * @returns {ViewTransform} */
export function viewTransform(lo, hi, pad = 28) {
  const span = Math.max(hi[0] - lo[0], hi[1] - lo[1]);
  const scale = (VIEW - 2 * pad) / span;
  // Centre the box: a long thin workspace is not drawn in a corner.
  const ox = pad + (VIEW - 2 * pad - (hi[0] - lo[0]) * scale) / 2;
  const oy = pad + (VIEW - 2 * pad - (hi[1] - lo[1]) * scale) / 2;
  return {
    lo, hi, scale,
    toSvg: (x, y) => [ox + (x - lo[0]) * scale, VIEW - oy - (y - lo[1]) * scale],
    toWorld: (sx, sy) => [lo[0] + (sx - ox) / scale, lo[1] + (VIEW - oy - sy) / scale],
  };
}

/** Latitude and longitude (degrees) of world point (x east, y north) for a geodetic origin
 * {lat, lon}: the local tangent plane on the WGS-84 ellipsoid, good to centimetres over a
 * few kilometres, which is all a fleet's workspace spans.
 * @param {LatLon} origin
 * @param {number} x
 * @param {number} y
 * @returns {LatLon} */
export function toGeodetic(origin, x, y) {
  const a = 6378137.0, e2 = 6.69437999014e-3;
  const phi = (origin.lat * Math.PI) / 180;
  const s = 1 - e2 * Math.sin(phi) ** 2;
  const rn = a / Math.sqrt(s);             // prime vertical radius
  const rm = (a * (1 - e2)) / s ** 1.5;    // meridian radius
  return {
    lat: origin.lat + ((y / rm) * 180) / Math.PI,
    lon: origin.lon + ((x / (rn * Math.cos(phi))) * 180) / Math.PI,
  };
}

/** The longest 1, 2 or 5 x 10^k metres not longer than `max` metres.
 * @param {number} max
 * @returns {number} */
export function niceLength(max) {
  if (!(max > 0)) return 1;
  const p = 10 ** Math.floor(Math.log10(max));
  for (const m of [5, 2, 1]) if (m * p <= max) return m * p;
  return p;
}

/** @param {number} d @param {string} pos @param {string} neg */
const fmtDeg = (d, pos, neg) => `${Math.abs(d).toFixed(6)}° ${d >= 0 ? pos : neg}`;
/** "47.397742° N 8.545594° E".
 * @param {LatLon} g
 * @returns {string} */
export const latLonText = (g) => `${fmtDeg(g.lat, "N", "S")} ${fmtDeg(g.lon, "E", "W")}`;

/** Draw what does not move: workspace, obstacles and their clearance, planned paths, starts and goals, scale bar, geodetic
 * corners. Returns the transform for `drawMoving`.
 * @param {SVGSVGElement} svg
 * @param {{lo: number[], hi: number[], origin: LatLon | null,
 *   paths: {id: string, color: string, points: number[][]}[],
 *   obstacles?: import("./obstacles.js").Obstacle[], clearance?: number}} scene
 * @returns {ViewTransform} */
export function drawStatic(svg, scene) {
  svg.innerHTML = "";
  const tf = viewTransform(scene.lo, scene.hi);
  const stat = svgEl("g", { class: "static" }, svg);
  const [x0, y0] = tf.toSvg(scene.lo[0], scene.lo[1]);
  const [x1, y1] = tf.toSvg(scene.hi[0], scene.hi[1]);
  svgEl("rect", { x: x0, y: y1, width: x1 - x0, height: y0 - y1, fill: "#fff", stroke: "#9aa4af" }, stat);
  drawObstacles(svgEl("g", { class: "obstacles" }, stat), tf, scene.obstacles ?? [], scene.clearance ?? 0);
  if (layered(scene.paths.length)) drawPathLayers(stat, tf, scene.paths);
  else {
    for (const path of scene.paths) {
      const pts = path.points.map(([x, y]) => tf.toSvg(x, y).map((v) => v.toFixed(1)).join(",")).join(" ");
      svgEl("polyline", { points: pts, fill: "none", stroke: path.color, "stroke-width": 1.2,
                          "stroke-opacity": 0.55, class: "planned-path", "data-id": path.id }, stat);
      svgEl("path", { d: cross(tf, path.points[path.points.length - 1], 4), stroke: path.color,
                      "stroke-width": 1.5 }, stat);
    }
  }
  // Scale bar: bottom left, about a quarter of the box.
  const metres = niceLength((scene.hi[0] - scene.lo[0]) / 4);
  const len = metres * tf.scale;
  const bx = x0, by = Math.min(VIEW - 8, y0 + 18);
  const bar = svgEl("g", { class: "scale-bar", "data-metres": metres }, stat);
  svgEl("path", { d: `M${bx},${by - 4}V${by}H${bx + len}V${by - 4}`, fill: "none", stroke: "#1d232b", "stroke-width": 1.5 }, bar);
  svgEl("text", { x: bx + len + 4, y: by, "font-size": 10, fill: "#1d232b" }, bar).textContent = `${metres} m`;
  /** @param {number} x @param {number} y @param {string} anchor @param {number} dy */
  const corner = (x, y, anchor, dy) => {
    const [sx, sy] = tf.toSvg(x, y);
    const text = scene.origin ? latLonText(toGeodetic(scene.origin, x, y)) : `(${x}, ${y}) m`;
    svgEl("text", { x: sx, y: sy + dy, "font-size": 9, fill: "#6b7480", "text-anchor": anchor,
                    class: "corner" }, stat).textContent = text;
  };
  corner(scene.lo[0], scene.hi[1], "start", -5);  // north-west corner
  corner(scene.hi[0], scene.lo[1], "end", 12);    // south-east corner
  if (scene.origin) {
    const nx = x1 + 12, ny = y1 + 4;
    svgEl("path", { d: `M${nx},${ny + 14}L${nx},${ny}M${nx - 4},${ny + 5}L${nx},${ny}L${nx + 4},${ny + 5}`, stroke: "#1d232b", fill: "none" }, stat);
    svgEl("text", { x: nx, y: ny + 24, "font-size": 9, "text-anchor": "middle" }, stat).textContent = "N";
  }
  svgEl("g", { class: "moving" }, svg);
  return tf;
}

/** SVG path data of a cross of half-size `r` at world point p.
 * @param {ViewTransform} tf @param {number[]} p @param {number} r @returns {string} */
function cross(tf, p, r) {
  const [gx, gy] = tf.toSvg(p[0], p[1]).map((v) => Math.round(v * 10) / 10);
  return `M${gx - r},${gy - r}L${gx + r},${gy + r}M${gx - r},${gy + r}L${gx + r},${gy - r}`;
}

/** SVG path data of a circle of radius r at world point p (two arcs).
 * @param {{toSvg: (x: number, y: number) => number[]}} tf @param {number[]} p
 * @param {number} r @returns {string} */
function ring(tf, p, r) {
  const [sx, sy] = tf.toSvg(p[0], p[1]);
  return `M${(sx + r).toFixed(1)},${sy.toFixed(1)}a${r},${r} 0 1,0 ${-2 * r},0a${r},${r} 0 1,0 ${2 * r},0`;
}

/** A show-sized fleet's paths and goals: one SVG path per colour (class planned-paths,
 * data-vehicles its vehicle count), each vehicle's path decimated to PATH_POINTS points.
 * @param {Element} layer @param {ViewTransform} tf
 * @param {{id: string, color: string, points: number[][]}[]} paths */
function drawPathLayers(layer, tf, paths) {
  for (const group of byColour(paths)) {
    const d = group.map((path) => decimated(path.points.length, PATH_POINTS).map((k, j) => {
      const [x, y] = tf.toSvg(path.points[k][0], path.points[k][1]);
      return `${j ? "L" : "M"}${x.toFixed(1)},${y.toFixed(1)}`;
    }).join("")).join("");
    svgEl("path", { d, fill: "none", stroke: group[0].color, "stroke-width": 1, "stroke-opacity": 0.4,
                    class: "planned-paths", "data-vehicles": group.length }, layer);
    const goals = group.map((path) => cross(tf, path.points[path.points.length - 1], 2)).join("");
    svgEl("path", { d: goals, stroke: group[0].color, "stroke-width": 1, class: "goal-marks" }, layer);
  }
}

/** Draw what moves: planned positions now (rings), trails, and the vehicles (live or
 * replayed) as filled, labelled icons.
 * @param {SVGSVGElement} svg
 * @param {{toSvg: (x: number, y: number) => number[]}} tf
 * @param {{planned: {id: string, color: string, position: number[]}[],
 *   vehicles: MovingVehicle[]}} moving */
export function drawMoving(svg, tf, moving) {
  const layer = svg.querySelector("g.moving");
  if (!layer) return;
  layer.innerHTML = "";
  if (layered(moving.planned.length)) {  // one path of rings per colour
    for (const group of byColour(moving.planned)) {
      svgEl("path", { d: group.map((p) => ring(tf, p.position, 3)).join(""), fill: "none",
                      stroke: group[0].color, "stroke-width": 1, class: "planned-icons",
                      "data-vehicles": group.length }, layer);
    }
  } else for (const p of moving.planned) {
    const [sx, sy] = tf.toSvg(p.position[0], p.position[1]);
    svgEl("circle", { cx: sx, cy: sy, r: 6, fill: "none", stroke: p.color, "stroke-width": 1.5,
                      "stroke-dasharray": "2 2", class: "planned-icon", "data-id": p.id }, layer);
  }
  for (const v of moving.vehicles) {
    if (v.trail && v.trail.length > 1) {
      const pts = v.trail.map(([x, y]) => tf.toSvg(x, y).map((c) => c.toFixed(1)).join(",")).join(" ");
      svgEl("polyline", { points: pts, fill: "none", stroke: v.color, "stroke-width": 2.2,
                          "stroke-opacity": 0.9, class: "trail", "data-id": v.id }, layer);
    }
  }
  for (const v of moving.vehicles) {
    if (!v.position) continue;
    const [sx, sy] = tf.toSvg(v.position[0], v.position[1]);
    const g = svgEl("g", { class: `vehicle-icon${v.alert ? " alert" : ""}`, "data-id": v.id,
                            transform: `translate(${sx.toFixed(1)},${sy.toFixed(1)})` }, layer);
    if (v.alert) svgEl("circle", { r: 10, fill: "none", stroke: "#c62828", "stroke-width": 2 }, g);
    // A small arrow along the horizontal velocity, a dot when hovering.
    const vel = v.velocity || [0, 0, 0];
    const speed = Math.hypot(vel[0], vel[1]);
    if (speed > 0.2) {
      const a = (Math.atan2(-vel[1], vel[0]) * 180) / Math.PI;
      svgEl("path", { d: "M9,0L-5,-6L-2,0L-5,6Z", fill: v.color, stroke: "#fff", "stroke-width": 1,
                      transform: `rotate(${a.toFixed(0)})` }, g);
    } else {
      svgEl("circle", { r: 5.5, fill: v.color, stroke: "#fff", "stroke-width": 1.2 }, g);
    }
    const alt = Number.isFinite(v.position[2]) ? `${v.position[2].toFixed(1)} m` : "";
    // Labels near the right edge go to the icon's left, so none is cut off.
    const left = sx > VIEW - 95;
    svgEl("text", { x: left ? -9 : 9, y: -8, "font-size": 11, class: "icon-label", fill: "#1d232b",
                    "text-anchor": left ? "end" : "start" }, g).textContent = `${v.id} ${alt}`;
  }
}
