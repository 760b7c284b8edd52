// @ts-check
// A finished flight replayed: its recorded positions against the plan, on the time slider,
// and its measured separation beside the planned one; closed when another flight or mission
// takes the screen.
import { $ } from "./dom.js";
import { horizon, moveSlider } from "./flyscreen.js";
import { renderSeparation } from "./planview.js";
import { flight, planning, views } from "./state.js";
import { measuredSeparation } from "./tracks.js";

/** Replay: recorded positions against the plan, on flight time (record t - flight_start).
 * @param {string} id
 * @param {any} record  GET /api/flights/{id}/record */
export function startReplay(id, record) {
  const t0 = record.flight_start ?? record.mission_start ?? 0;  // mission_start: older records
  flight.replay = {
    id,
    vehicles: record.vehicles.map((/** @type {any} */ v) => ({
      id: v.id, t: v.telemetry.t.map((/** @type {number} */ t) => t - t0), position: v.telemetry.position,
    })).filter((/** @type {{t: number[]}} */ v) => v.t.length),
  };
  const plan = planning.mission && planning.mission.plan;
  const scale = (plan && plan.scenario.separation_scale) || [1, 1, 1];
  views.measured = measuredSeparation(flight.replay.vehicles, scale, horizon());
  if (views.measured) views.measured.label = `measured (flight ${id})`;
  if (views.sepTraj && plan) renderSeparation(plan, views.sepTraj);
  $("#follow").checked = false;
  moveSlider(Number($("#time-slider").max));  // the end: where everyone went; ▶ replays it
}

/** Leave the replay shown, if any. */
export function closeReplay() {
  if (!flight.replay) return;
  flight.replay = null;
  views.measured = null;
  const plan = planning.mission && planning.mission.plan;
  if (views.sepTraj && plan) renderSeparation(plan, views.sepTraj);
}
