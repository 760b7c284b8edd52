// @ts-check
// Positions over time: interpolating a recorded track, and the minimum pairwise distance of
// a fleet (planned or recorded) in the plan's separation metric ||diag(1/scale) d||.
/** Linear interpolation of a track (times, points) at time t, held at its ends.
 * @param {number[]} times @param {number[][]} points @param {number} t
 * @returns {number[] | null} */
export function sampleAt(times, points, t) {
  if (!times.length) return null;
  if (t <= times[0]) return points[0];
  if (t >= times[times.length - 1]) return points[points.length - 1];
  let lo = 0, hi = times.length - 1;
  while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (times[mid] <= t) lo = mid; else hi = mid; }
  const w = (t - times[lo]) / (times[hi] - times[lo] || 1);
  return points[lo].map((p, a) => p + w * (points[hi][a] - p));
}

/** The smallest scaled distance between any two of `points` ([[x, y, z]...]): a sweep
 * along the axis the points spread most on, so a show-sized fleet costs about n log n
 * rather than n² (pairs farther apart on that axis than the best so far are skipped).
 * @param {number[][]} points @param {number[]} scale @returns {number} */
export function closestPair(points, scale) {
  const n = points.length;
  let axis = 0, widest = -1;
  for (let a = 0; a < 3; a++) {
    let lo = Infinity, hi = -Infinity;
    for (const p of points) { const c = p[a] / scale[a]; if (c < lo) lo = c; if (c > hi) hi = c; }
    if (hi - lo > widest) { widest = hi - lo; axis = a; }
  }
  const key = points.map((p) => p[axis] / scale[axis]);
  const order = Array.from({ length: n }, (_, i) => i).sort((i, j) => key[i] - key[j]);
  let best = Infinity;
  for (let a = 0; a < n; a++) {
    const p = points[order[a]];
    for (let b = a + 1; b < n; b++) {
      if (key[order[b]] - key[order[a]] >= best) break;
      const q = points[order[b]];
      const d = Math.hypot((p[0] - q[0]) / scale[0], (p[1] - q[1]) / scale[1], (p[2] - q[2]) / scale[2]);
      if (d < best) best = d;
    }
  }
  return best;
}

/** Planned minimum separation at every sample of a /trajectory answer: {t, d}.
 * @param {{scenario: {separation_scale?: number[]}}} plan
 * @param {{t: number[], vehicles: {position: number[][]}[]}} traj
 * @returns {{t: number[], d: number[]}} */
export function minSeparation(plan, traj) {
  const scale = plan.scenario.separation_scale || [1, 1, 1];
  const d = traj.t.map((_, k) => closestPair(traj.vehicles.map((v) => v.position[k]), scale));
  return { t: traj.t, d };
}

/** Measured minimum separation of recorded tracks [{t, position}...], 5 per second over
 * [0, end] (flight time): {t, d}, or null with fewer than two tracks.
 * @param {{t: number[], position: number[][]}[]} tracks
 * @param {number[]} scale
 * @param {number} end
 * @returns {{t: number[], d: number[], label?: string} | null} */
export function measuredSeparation(tracks, scale, end) {
  if (tracks.length < 2) return null;
  const t = [], d = [];
  for (let k = 0; k * 0.2 <= end + 1e-9; k++) {
    const s = k * 0.2;
    t.push(Number(s.toFixed(3)));
    // Every track has samples, so sampleAt gives a point.
    d.push(closestPair(tracks.map((v) => /** @type {number[]} */ (sampleAt(v.t, v.position, s))), scale));
  }
  return { t, d };
}

/** A show's light colour at time t from its changes ([start, end, "#rrggbb"] rows in time
 * order, GET /trajectory's `lights`): dark before the first, each reached linearly over
 * [start, end] from what showed at start.
 * @param {[number, number, string][]} changes @param {number} t @returns {string} */
export function lightAt(changes, t) {
  let rgb = [0, 0, 0];
  for (const [start, end, hex] of changes) {
    if (t < start) break;
    const target = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
    const w = t >= end ? 1 : (t - start) / (end - start);
    rgb = rgb.map((c, a) => c + w * (target[a] - c));
    if (t < end) break;
  }
  return `#${rgb.map((c) => Math.round(c).toString(16).padStart(2, "0")).join("")}`;
}
