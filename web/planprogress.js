// @ts-check
// A plan being computed, as the page shows it: the iteration under way and the work done
// inside it (groups solved, batches done of how many, an estimate where the service gives
// one), the time since Plan was pressed, and Cancel (POST /api/missions/{id}/cancel).
import { api } from "./api.js";
import { $ } from "./dom.js";
import { planning } from "./state.js";

/** Seconds as the page says them: "42 s", "3 min 5 s".
 * @param {number} s */
export function duration(s) {
  const whole = Math.max(0, Math.round(s));
  return whole < 60 ? `${whole} s` : `${Math.floor(whole / 60)} min ${whole % 60} s`;
}

/** " · batch 3/8" for a record or report of prioritized batches, else "".
 * @param {any} r */
const batchOf = (r) => (r && r.batch !== null && r.batch !== undefined ? ` · batch ${r.batch}/${r.batches}` : "");

/** The plan state after an SCP iteration's record.
 * @param {any} r */
export function iterationState(r) {
  const leg = (r.leg === undefined || r.leg === null) ? "" : `leg ${r.leg}, `;
  return `planning… ${leg}iteration ${r.iteration}${batchOf(r)}${r.method ? ` · ${r.method}` : ""}`;
}

/** The plan state from a `working` event (the mission's `planning` summary): the groups
 * solved inside the iteration under way, and the time left where it can be estimated.
 * @param {any} summary */
export function workingState(summary) {
  const w = summary.working;
  if (!w) return "planning…";
  const leg = (w.leg === undefined || w.leg === null) ? "" : `leg ${w.leg}, `;
  const round = w.round > 1 ? ` (round ${w.round})` : "";
  const b = summary.batches;
  const left = b && b.remaining_s !== null ? `, about ${duration(b.remaining_s)} left` : "";
  return `planning… ${leg}iteration ${w.iteration}: ${w.groups_done}/${w.groups} groups solved${round} ` +
    `(largest ${w.largest_group} vehicles, ${w.separation_rows} rows), ${w.qp_solves} QP solves` +
    `${batchOf(w)}${left}${w.method ? ` · ${w.method}` : ""}`;
}

let ticker = 0;

/** The elapsed time beside the plan state, once a second, and Cancel, while `id` plans.
 * @param {string} id */
export function planningStarted(id) {
  planning.planningId = id;
  $("#plan-cancel").hidden = false;
  $("#plan-cancel").disabled = false;
  const tick = () => { $("#plan-elapsed").textContent = `${duration((Date.now() - planning.startedAt) / 1000)} elapsed`; };
  tick();
  clearInterval(ticker);
  ticker = window.setInterval(tick, 1000);
}

/** Planning over (planned, failed, refused or cancelled): no Cancel, no clock. */
export function planningEnded() {
  planning.planningId = null;
  planning.startedAt = 0;
  clearInterval(ticker);
  $("#plan-cancel").hidden = true;
  $("#plan-elapsed").textContent = "";
}

/** Cancel: the service stops the computation; the mission ends `failed` ("cancelled by the
 * operator"), which the planning stream then shows. */
export async function cancelPlanning() {
  const id = planning.planningId;
  if (!id) return;
  $("#plan-cancel").disabled = true;
  $("#plan-state").textContent = "cancelling…";
  const { ok, status, data } = await api("POST", `/api/missions/${id}/cancel`);
  if (!ok && status !== 409) {  // 409: it ended meanwhile; the stream shows how
    $("#plan-cancel").disabled = false;
    $("#plan-state").textContent = `cancel refused (${status}): ${data.reason ?? ""}`;
  }
}
