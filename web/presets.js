// @ts-check
// Generated presets: a circle swap and a random fleet of any size, with limits and a horizon
// long enough for them. Pure functions: scenario JSON out.
/** @typedef {import("./state.js").Scenario} Scenario */

/** Steps for a move of `distance` metres.
 * @param {number} distance @param {number} dt @returns {number} */
function transferSteps(distance, dt) {
  // Time for a rest-to-rest move at 2 m/s, 3 m/s², with slack for avoidance manoeuvres.
  const t = distance / 2 + 2 / 3;
  return Math.ceil((1.6 * t + 4) / dt);
}

/** n vehicles swapping places across a circle.
 * @param {number} n @returns {Scenario} */
export function circleScenario(n) {
  const R = 1.0;
  const radius = Math.max(2.5, (1.6 * n * R) / (2 * Math.PI));
  const c = radius + 1;
  const vehicles = [];
  for (let i = 0; i < n; i++) {
    const a = (2 * Math.PI * i) / n;
    const z = i % 2 ? 1.9 : 1.1;
    const start = [c + radius * Math.cos(a), c + radius * Math.sin(a), z];
    const goal = [c - radius * Math.cos(a), c - radius * Math.sin(a), z];
    vehicles.push({ id: `uav${i + 1}`, start: start.map(round2), goal: goal.map(round2) });
  }
  return {
    name: `circle${n}`, dt: 0.2, steps: transferSteps(2 * radius, 0.2), min_separation: R,
    limits: standardLimits([2 * c, 2 * c, 3]), vehicles,
  };
}

/** n vehicles at random starts and goals, at least 1.5 R apart; the starts also R apart in
 * x-y, so vehicles standing under them climb to them without meeting.
 * @param {number} n @returns {Scenario} */
export function randomScenario(n) {
  const R = 1.0;
  const side = Math.max(5, Math.ceil(Math.sqrt(n * 6)));
  const size = [side, side, 4];
  /** @param {number[][]} taken @param {boolean} columns @returns {number[]} */
  const pick = (taken, columns) => {
    for (let tries = 0; tries < 10000; tries++) {
      const p = [0.5 + Math.random() * (side - 1), 0.5 + Math.random() * (side - 1),
                 1 + Math.random() * 2.5].map(round2);
      if (taken.every((q) => Math.hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]) >= 1.5 * R &&
                             (!columns || Math.hypot(p[0] - q[0], p[1] - q[1]) >= R))) return p;
    }
    throw new Error("workspace too crowded");
  };
  /** @type {number[][]} */
  const starts = [];
  /** @type {number[][]} */
  const goals = [];
  for (let i = 0; i < n; i++) { starts.push(pick(starts, true)); goals.push(pick(goals, false)); }
  const far = Math.max(...starts.map((s, i) => Math.hypot(...s.map((v, a) => v - goals[i][a]))));
  return {
    name: `random${n}`, dt: 0.2, steps: transferSteps(far, 0.2), min_separation: R,
    limits: standardLimits(size),
    vehicles: starts.map((s, i) => ({ id: `uav${i + 1}`, start: s, goal: goals[i] })),
  };
}

/** @param {number} x @returns {number} */
export const round2 = (x) => Math.round(x * 100) / 100;
/** @param {number[]} max */
const standardLimits = (max) => ({
  position_min: [0, 0, 0], position_max: max.map(round2),
  velocity_max: [2, 2, 2], acceleration_max: [3, 3, 3], jerk_max: [5, 5, 5],
});
