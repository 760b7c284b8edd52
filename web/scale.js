// @ts-check
// The page at show scale: above LAYERED_ABOVE vehicles every view draws one element (plot
// trace or SVG path) per colour, carrying all that colour's vehicles as separate segments,
// from paths decimated to at most PATH_POINTS points, and trajectories are fetched at a rate
// that keeps vehicles x samples within SAMPLE_BUDGET. Smaller fleets are drawn one element
// per vehicle from the full samples.
/** Fleets larger than this are drawn one layer per colour, not one element per vehicle. */
export const LAYERED_ABOVE = 32;
/** Most points of one vehicle's path in a layered drawing. */
export const PATH_POINTS = 16;
/** Most vehicle-time samples the page fetches in one trajectory answer. */
export const SAMPLE_BUDGET = 40_000;

/** Whether a fleet of `count` vehicles is drawn in layers.
 * @param {number} count @returns {boolean} */
export const layered = (count) => count > LAYERED_ABOVE;

/** The trajectory rate (Hz) to fetch: `wanted`, or lower so that every vehicle's samples
 * over the horizon stay within SAMPLE_BUDGET (one decimal: a rate the URL shows plainly).
 * @param {number} wanted @param {number} vehicles @param {number} horizon @returns {number} */
export function trajectoryRate(wanted, vehicles, horizon) {
  const most = SAMPLE_BUDGET / Math.max(1, vehicles) / Math.max(horizon, 1e-9);
  if (wanted <= most) return wanted;
  return Math.max(0.1, Math.floor(most * 10) / 10);
}

/** Indices of at most `most` samples of `length`, evenly spread, first and last kept.
 * @param {number} length @param {number} most @returns {number[]} */
export function decimated(length, most) {
  if (length <= most) return Array.from({ length }, (_, i) => i);
  const out = [];
  for (let j = 0; j < most; j++) out.push(Math.round((j * (length - 1)) / (most - 1)));
  return out;
}

/** Items grouped by their colour, in first-seen order: one layer each.
 * @template {{color: string}} T @param {T[]} items @returns {T[][]} */
export function byColour(items) {
  /** @type {Map<string, T[]>} */
  const groups = new Map();
  for (const item of items) {
    if (!groups.has(item.color)) groups.set(item.color, []);
    groups.get(item.color)?.push(item);
  }
  return Array.from(groups.values());
}
