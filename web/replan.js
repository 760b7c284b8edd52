// @ts-check
// Replanning the flight under way: drag a vehicle's goal marker in the fly view (or type
// its goal) and send the new goals, or drop a vehicle from the fleet table to land or hold;
// each is POST /api/flights/{id}/replan. The replan's state comes from the flight's live
// state (its `replan` object); once the flight's plans change, the views show the plans
// flown (GET /api/flights/{id}/trajectory: the first plan, then each switched replan's).
import { api, errorsOf } from "./api.js";
import { showVehicleTable } from "./fleettable.js";
import { $, clamp, color, fmt, svgEl } from "./dom.js";
import { drawFlyStatic, setTime } from "./flyscreen.js";
import { VIEW } from "./flyview.js";
import { layered } from "./scale.js";
import { fleet, flight, planning, replan, views } from "./state.js";

/** @typedef {import("./state.js").ReplanObject} ReplanObject */

/** Replanning is offered: the service has the route and a flight is under way. */
export const replanOffered = () => Boolean(fleet.caps.replan && flight.active && flight.id);

/** Whether the views' plan has dropped this vehicle (it lands or holds on its own).
 * @param {string} id */
export const isDropped = (id) => Boolean(replan.dropped[id] !== undefined);

/** A vehicle's goal in the views' plan (its last planned position).
 * @param {string} id
 * @returns {number[] | null} */
function goalOf(id) {
  const v = views.traj && views.traj.vehicles.find((w) => w.id === id);
  return v ? v.position[v.position.length - 1] : null;
}

/** The workspace box of the mission shown: [lo, hi]. */
function workspace() {
  const lim = planning.mission && planning.mission.plan && planning.mission.plan.scenario.limits;
  return lim ? [lim.position_min, lim.position_max] : null;
}

// ------------------------------------------------------------------ the goal markers

/** Draw (or clear) the draggable goal markers and the goals being edited, on top of the
 * fly view; a show-sized fleet's view has none (its goals are changed through the API). */
export function drawGoalMarkers() {
  const svg = $("#fly-view");
  let layer = svg.querySelector("g.goal-markers");
  if (!layer) layer = svgEl("g", { class: "goal-markers" }, svg);
  else svg.appendChild(layer);  // above what moves
  layer.innerHTML = "";
  const tf = views.flyTf;
  if (!replanOffered() || !tf || !views.traj || layered(views.traj.vehicles.length)) return;
  views.traj.vehicles.forEach((v, i) => {
    const goal = goalOf(v.id);
    if (!goal || isDropped(v.id)) return;
    const [gx, gy] = tf.toSvg(goal[0], goal[1]);
    const edited = replan.pending[v.id];
    if (edited) {
      const [ex, ey] = tf.toSvg(edited[0], edited[1]);
      svgEl("line", { x1: gx, y1: gy, x2: ex, y2: ey, stroke: color(i), "stroke-width": 1.5,
                      "stroke-dasharray": "3 2" }, layer);
      svgEl("circle", { cx: ex, cy: ey, r: 7, fill: color(i), "fill-opacity": 0.35, stroke: color(i),
                        "stroke-width": 2, class: "goal-edited", "data-id": v.id }, layer);
    }
    // The marker stays where the plan's goal is until the new goal is flown.
    svgEl("circle", { cx: gx, cy: gy, r: 8, fill: "#fff", "fill-opacity": 0.01, stroke: color(i),
                      "stroke-width": 2, class: "goal-marker", "data-id": v.id }, layer)
      .appendChild(svgEl("title", {})).textContent = `${v.id}'s goal: drag to move it`;
  });
}

/** The world point (x, y) under a pointer on the fly view. @param {PointerEvent} ev */
function worldAt(ev) {
  const box = $("#fly-view").getBoundingClientRect();
  const tf = /** @type {NonNullable<typeof views.flyTf>} */ (views.flyTf);
  return tf.toWorld(((ev.clientX - box.left) / box.width) * VIEW, ((ev.clientY - box.top) / box.height) * VIEW);
}

/** A goal marker pressed: its goal is being edited (a press alone opens it for typing).
 * @param {PointerEvent} ev */
export function onGoalPointerDown(ev) {
  const marker = /** @type {Element} */ (ev.target).closest && /** @type {Element} */ (ev.target).closest(".goal-marker, .goal-edited");
  if (!marker || !replanOffered()) return;
  const id = /** @type {string} */ (marker.getAttribute("data-id"));
  const goal = goalOf(id);
  if (!goal) return;
  ev.preventDefault();
  replan.drag = id;
  if (!replan.pending[id]) replan.pending[id] = goal.slice(0, 3);
  $("#fly-view").setPointerCapture(ev.pointerId);
  showReplanPanel();
}

/** @param {PointerEvent} ev */
export function onGoalPointerMove(ev) {
  if (!replan.drag || !views.flyTf) return;
  const box = workspace();
  const [x, y] = worldAt(ev);
  const goal = replan.pending[replan.drag];
  goal[0] = box ? clamp(x, box[0][0], box[1][0]) : x;
  goal[1] = box ? clamp(y, box[0][1], box[1][1]) : y;
  drawGoalMarkers();
  showPendingValues();
}

export function onGoalPointerUp() {
  if (!replan.drag) return;
  replan.drag = null;
  drawGoalMarkers();
  showReplanPanel();
}

// ------------------------------------------------------------------ the replan panel

/** The panel and the goal markers as the flight shown allows (a flight started or ended). */
export function updateReplanControls() {
  showReplanPanel();
  drawGoalMarkers();
}

/** The replan controls: shown while a flight can be replanned, the goals being edited in
 * their rows. */
export function showReplanPanel() {
  const panel = $("#replan-panel");
  panel.hidden = !replanOffered();
  if (panel.hidden) return;
  const body = $("#replan-goals tbody");
  const ids = Object.keys(replan.pending);
  const want = ids.join(",");
  if (body.dataset.ids !== want) {  // rebuilt only when the vehicles edited change
    body.dataset.ids = want;
    body.innerHTML = "";
    for (const id of ids) body.appendChild(goalRow(id));
  }
  showPendingValues();
  $("#replan-goals").hidden = ids.length === 0;
  $("#replan-send").disabled = ids.length === 0 || replan.sending;
  $("#replan-cancel").hidden = ids.length === 0;
}

/** One edited goal: its id, x, y, z inputs and a remove button. @param {string} id */
function goalRow(id) {
  const tr = document.createElement("tr");
  tr.dataset.id = id;
  const name = document.createElement("td");
  name.textContent = id;
  tr.appendChild(name);
  for (let axis = 0; axis < 3; axis++) {
    const td = document.createElement("td");
    const input = document.createElement("input");
    input.type = "number";
    input.step = "any";
    input.dataset.field = `goals.${id}[${axis}]`;
    input.setAttribute("aria-label", `${id} goal ${"xyz"[axis]}`);
    input.addEventListener("input", () => {
      const value = Number(input.value);
      if (input.value !== "" && Number.isFinite(value)) replan.pending[id][axis] = value;
      drawGoalMarkers();
    });
    td.appendChild(input);
    tr.appendChild(td);
  }
  const td = document.createElement("td");
  const remove = document.createElement("button");
  remove.type = "button";
  remove.className = "mini";
  remove.textContent = "✕";
  remove.title = `keep ${id}'s goal`;
  remove.addEventListener("click", () => { delete replan.pending[id]; drawGoalMarkers(); showReplanPanel(); });
  td.appendChild(remove);
  tr.appendChild(td);
  return tr;
}

/** The edited goals' inputs show their values (unless the operator is typing in one). */
function showPendingValues() {
  for (const input of /** @type {HTMLInputElement[]} */ (Array.from($("#replan-goals").querySelectorAll("input")))) {
    if (input === document.activeElement) continue;
    const [, id, axis] = /** @type {RegExpMatchArray} */ (input.dataset.field?.match(/^goals\.(.*)\[(\d)\]$/));
    const goal = replan.pending[id];
    if (goal) input.value = String(Math.round(goal[Number(axis)] * 100) / 100);
  }
}

/** Forget the goals being edited. */
export function cancelGoals() {
  replan.pending = {};
  $("#replan-error").textContent = "";
  drawGoalMarkers();
  showReplanPanel();
}

/** Send the edited goals as one replan. */
export async function sendGoals() {
  const goals = Object.fromEntries(Object.entries(replan.pending).map(([id, g]) => [id, g.slice(0, 3)]));
  if (!Object.keys(goals).length) return;
  if (await requestReplan({ goals })) cancelGoals();
}

/** Drop a vehicle from the plan: it lands (or holds, as chosen) on its own motion, which the
 * others' new plan keeps clear of. @param {string} id */
export async function dropVehicle(id) {
  await requestReplan({ drop: [id], drop_action: $("#drop-action").value });
}

/** POST the replan; its answer or refusal shown. @param {Record<string, unknown>} body
 * @returns {Promise<boolean>} accepted */
async function requestReplan(body) {
  const id = flight.id;
  if (!id || replan.sending) return false;
  replan.sending = true;
  showReplanPanel();
  $("#replan-error").textContent = "";
  const r = await api("POST", `/api/flights/${id}/replan`, body);
  replan.sending = false;
  showReplanPanel();
  if (!r.ok) {
    $("#replan-error").textContent = `replan refused (${r.status}): ` +
      errorsOf(r.data).map((e) => (e.field ? `${e.field}: ${e.reason}` : e.reason)).join("; ");
    return false;
  }
  showReplanStatus(r.data.replan);
  return true;
}

// ------------------------------------------------------------------ the replan's state

/** The last replan's state in words, from its object.
 * @param {ReplanObject | null | undefined} obj */
export function showReplanStatus(obj) {
  const el = $("#replan-status");
  if (!obj) { el.textContent = ""; el.className = "small"; delete el.dataset.status; return; }
  replan.current = obj;
  const parts = [`replan ${obj.id}: ${obj.status}`, `switch at t = ${fmt(obj.switch_time, 2)} s`];
  if (obj.planning_s !== null && obj.planning_s !== undefined) parts.push(`planned in ${fmt(obj.planning_s, 3)} s`);
  const changed = [...Object.keys(obj.goals || {}).map((v) => `${v} new goal`),
                   ...(obj.drop || []).map((v) => `${v} ${obj.drop_action}s`)];
  if (changed.length) parts.push(changed.join(", "));
  if (obj.why) parts.push(obj.why);
  el.textContent = parts.join(" · ");
  el.dataset.status = obj.status;
  el.className = `small ${obj.why ? "bad" : (obj.planning_s !== null && obj.planning_s !== undefined ? "ok" : "")}`;
}

/** A telemetry snapshot: its replan shown; once the flight's replans change, the plans
 * flown are fetched and drawn. @param {import("./state.js").Telemetry} t */
export function replanTelemetry(t) {
  if ($("#replan-panel").hidden === replanOffered()) updateReplanControls();  // offered now, or no longer
  const obj = t.replan;
  if (!obj) return;
  const key = `${obj.id}:${obj.status}`;
  if (key === replan.seen) return;
  replan.seen = key;
  showReplanStatus(obj);
  if (flight.id) showFlownPlans(flight.id);
}

/** GET the plans flight `id` flew (so far); the views show them when they differ from what
 * is drawn (a replanned flight followed live, or replayed).
 * @param {string} id */
export async function showFlownPlans(id) {
  const shown = replan.planTraj || views.traj;
  if (!shown) { replan.seen = ""; return; }  // no plan on screen yet: the next snapshot
  const r = await api("GET", `/api/flights/${id}/trajectory?rate=${shown.rate}`);
  if (!r.ok || id !== flight.id) { replan.seen = ""; return; }
  const switches = (r.data.switches || []).map((/** @type {{replan: number}} */ s) => s.replan).join(",");
  if (switches === replan.drawn) return;
  replan.drawn = switches;
  replan.dropped = r.data.dropped || {};
  if (!replan.planTraj) replan.planTraj = views.traj;
  views.traj = r.data;
  const slider = $("#time-slider");
  slider.max = r.data.t.length - 1;
  drawFlyStatic();
  setTime(Number(slider.value));
  showVehicleTable();
}

/** The mission's plan has just been drawn (`planning.renderPlan`): the plans flown are
 * fetched again on the next snapshot. */
export function missionPlanShown() {
  replan.planTraj = null;
  replan.drawn = "";
  replan.seen = "";
  replan.dropped = {};
}

/** A new flight (or none): the mission's own plan in the views again, nothing edited.
 * @returns {boolean} whether the views' plan changed back */
export function resetReplan() {
  const restored = Boolean(replan.planTraj);
  if (replan.planTraj) views.traj = replan.planTraj;
  replan.planTraj = null;
  replan.pending = {};
  replan.drag = null;
  replan.current = null;
  replan.seen = "";
  replan.drawn = "";
  replan.dropped = {};
  showReplanStatus(null);
  $("#replan-error").textContent = "";
  return restored;
}
