// @ts-check
// Planning: the form's scenario (or a pasted sequence) sent to the service, its progress
// followed, and the mission's plan shown, tables, figures and fly view, once it is done.
// Plan stays disabled until the page holds its state and while a plan is being computed.
import { api, errorsOf } from "./api.js";
import { MISSIONS_CHANGED, MISSION_SHOWN, emit } from "./bus.js";
import { $, appendScrolled, badge, fmt } from "./dom.js";
import { clearErrors, errorItem, showError } from "./fielderrors.js";
import { refreshStale } from "./flygate.js";
import { clearFlightView, drawFlyStatic, resetSlider } from "./flyscreen.js";
import { readScenario, sequenceKey } from "./form.js";
import { loadPlotly, nextTask, renderFigures } from "./planview.js";
import { missionPlanShown } from "./replan.js";
import { iterationState, planningEnded, planningStarted, workingState } from "./planprogress.js";
import { closeReplay } from "./replay.js";
import { trajectoryRate } from "./scale.js";
import { boxDocument, documentKind } from "./upload.js";
import { flight, missionIs, planning, ready, views } from "./state.js";

/** @typedef {import("./state.js").Mission} Mission */

/** Plan, Plan sequence and Load preset: enabled once the page is ready, Plan and Plan
 * sequence not while a plan is being computed. */
export function updatePlanButtons() {
  const busy = !ready() || planning.planning;
  $("#plan-button").disabled = busy;
  $("#sequence-plan").disabled = busy;
  $("#preset-load").disabled = !ready();
}

/** Stop following the planning progress shown. */
export function closePlanStream() {
  if (planning.stream) { planning.stream.close(); planning.stream = null; }
}

/** Send a scenario (or sequence); its errors go where `refused` puts them.
 * @param {unknown} body
 * @param {string} key  the form or sequence it was read from
 * @param {string} what  what to see for the errors ("the fields marked")
 * @param {(errors: {field?: string, reason: string}[]) => void} refused */
async function send(body, key, what, refused) {
  closePlanStream();
  loadPlotly().catch(() => {});  // fetched while the plan is computed, not before
  planning.planning = true;
  planning.rejected = false;
  planning.pendingKey = key;
  refreshStale();
  updatePlanButtons();
  $("#plan-state").textContent = "submitting…";
  planning.startedAt = Date.now();
  $("#progress-log").innerHTML = "";
  $("#progress-log").hidden = false;
  const { status, data } = await api("POST", "/api/missions?wait=0", body);
  if (status !== 201 && status !== 202) {
    planningEnded();
    planning.planning = false;
    planning.rejected = true;
    updatePlanButtons();
    $("#plan-state").textContent = "";
    $("#plan-state").append(badge(false, `rejected (${status}): see ${what}`));
    refused(errorsOf(data));
    refreshStale();
    return;
  }
  followPlanning(data, key);
}

/** Plan: the form's scenario.
 * @param {Event} ev */
export async function submitPlan(ev) {
  ev.preventDefault();
  if (!ready() || planning.planning) return;  // the button is disabled then
  clearErrors();
  const scenario = readScenario();
  await send(scenario, JSON.stringify(scenario), "the fields marked",
    (errors) => { for (const e of errors) showError(e.field, e.reason); });
}

/** Plan or upload the JSON pasted, chosen or dropped: a scenario or a formation sequence is
 * planned (one mission; a sequence's legs in parallel), a plan is verified again and stored. */
export async function submitSequence() {
  if (!ready() || planning.planning) return;
  clearErrors();
  const box = $("#sequence-error");
  const { doc, error } = boxDocument();
  if (error) { box.append(errorItem("json", error)); return; }
  if (!documentKind(doc)) {
    box.append(errorItem("json", "must be a JSON object: a scenario (with vehicles), a formation " +
      "sequence (with formations) or a plan from fleetplan plan (with status and scenario)"));
    return;
  }
  await send(doc, sequenceKey(), "the errors under the JSON",
    (errors) => { for (const e of errors) box.append(errorItem(fieldText(e), e.reason)); });
}

/** An error's field, with its vehicle's id when the service names one.
 * @param {{field?: string, vehicle?: string}} e */
const fieldText = (e) => (e.field || "") + (e.vehicle ? ` (vehicle ${e.vehicle})` : "");

/** A sequence's plan: its formations and timeline, and its show-tool CSVs to download.
 * @param {Mission} mission */
function renderSequence(mission) {
  const info = $("#sequence-info");
  const seq = mission.plan && mission.plan.sequence;
  info.innerHTML = "";
  info.hidden = !seq;
  if (!seq) return;
  const names = seq.formations.map((/** @type {any} */ f) => f.name).join(" → ");
  const legs = seq.legs.map((/** @type {any} */ l) => `${l.status}, ${l.iterations} SCP iterations`).join("; ");
  const head = document.createElement("div");
  head.id = "sequence-summary";
  head.textContent = `sequence: ${names} · ${fmt(seq.duration_s, 1)} s · legs: ${legs}`;
  info.append(head);
  const links = document.createElement("div");
  links.id = "sequence-downloads";
  links.append("show-tool CSV (time ms, x, y, z), 10 Hz: ");
  for (const id of seq.vehicles) {
    const a = document.createElement("a");
    a.href = `/api/missions/${mission.id}/trajectory?format=show-csv&rate=10&vehicle=${encodeURIComponent(id)}`;
    a.download = `${id}.csv`;
    a.textContent = id;
    links.append(a, " ");
  }
  info.append(links);
}

/** The stored mission's files to keep: what each link is, its route and the name it saves as. */
const DOWNLOADS = [
  ["plan (JSON)", "plan", "plan-{id}.json"],
  ["trajectory CSV, 20 Hz", "trajectory?rate=20&format=csv", "trajectory-{id}.csv"],
  ["Skybrush show (.skyc)", "show.skyc", "show-{id}.skyc"],
  ["validation report (HTML)", "report.html", "report-{id}.html"],
];

/** Links to the mission's plan, trajectory, show file and validation report.
 * @param {Mission} mission */
function renderDownloads(mission) {
  const box = $("#plan-downloads");
  box.innerHTML = "";
  box.append("download: ");
  DOWNLOADS.forEach(([label, route, name], i) => {
    const a = document.createElement("a");
    a.href = `/api/missions/${mission.id}/${route}`;
    a.download = name.replace("{id}", mission.id);
    a.dataset.download = route.split(/[?.]/)[0];
    a.textContent = label;
    box.append(i ? " · " : "", a);
  });
}

/** One line of the progress log: an SCP iteration (live event or the plan's own record).
 * @param {any} r
 * @returns {HTMLLIElement} */
function iterationItem(r) {
  const li = document.createElement("li");
  const leg = (r.leg === undefined || r.leg === null) ? "" : `leg ${r.leg}, `;
  li.textContent = `${leg}iteration ${r.iteration}: cost ${fmt(r.cost, 2)}` +
    (r.cost_change === null ? "" : ` (Δ ${fmt(r.cost_change, 3)})`) +
    `, ${r.separation_rows} separation rows, ${r.qp_solves} QP solves, ${fmt(r.seconds, 3)} s` +
    (r.method ? ` · ${r.method}` : "") + (r.batch ? ` batch ${r.batch}/${r.batches}` : "");
  return li;
}

/** The progress log holds every iteration of the plan shown: a plan that finished before its
 * stream was followed (a quick plan, a busy browser) is listed from the plan's own record, and
 * so is one whose method raced another (the stream carried the other's iterations too).
 * @param {any} plan */
function completeProgressLog(plan) {
  const log = $("#progress-log");
  const iterations = Array.isArray(plan.iterations) ? plan.iterations : [];
  // (a stitched sequence's plan records no iterations of its own: its legs' lines stay)
  if (!iterations.length || log.children.length === iterations.length) return;
  log.innerHTML = "";
  for (const r of iterations) log.append(iterationItem(r));
}

/** Follow a mission being planned (its SCP iterations), then show it.
 * @param {Mission} mission
 * @param {string | null} key */
function followPlanning(mission, key) {
  $("#plan-state").textContent = "planning…";
  if (!missionIs(mission.status, "active")) { showMission(mission.id, key); return; }
  // a mission opened while it plans (not sent from here): its clock starts at its creation
  if (!planning.startedAt) planning.startedAt = Date.parse(mission.created_at) || Date.now();
  planningStarted(mission.id);
  const source = new EventSource(`/api/missions/${mission.id}/events`);
  planning.stream = source;
  source.addEventListener("iteration", (ev) => {
    const r = JSON.parse(ev.data);
    appendScrolled($("#progress-log"), iterationItem(r));
    $("#plan-state").textContent = iterationState(r);
  });
  source.addEventListener("working", (ev) => { $("#plan-state").textContent = workingState(JSON.parse(ev.data)); });
  source.addEventListener("done", () => { source.close(); planning.stream = null; showMission(mission.id, key); });
  source.onerror = () => {  // stream lost: fall back to polling the mission
    source.close();
    planning.stream = null;
    setTimeout(() => showMission(mission.id, key), 1000);
  };
}

/** Show a mission's plan. `key` is the form it was planned from (or loaded into).
 * @param {string} id
 * @param {string | null} key */
export async function showMission(id, key) {
  const { ok, data } = await api("GET", `/api/missions/${id}`);
  if (!ok) { $("#plan-state").textContent = data.reason; finishPlanning(); return; }
  if (missionIs(data.status, "active")) { followPlanning(data, key); return; }
  finishPlanning();
  emit(MISSIONS_CHANGED);
  if (missionIs(data.status, "failed") || !data.plan) {
    planning.rejected = true;
    $("#plan-state").innerHTML = "";
    $("#plan-state").append(badge(false, `planning failed: ${data.error ? data.error.reason : data.status}`));
    if (data.error && data.error.field) showError(data.error.field, data.error.reason);
    refreshStale();
    return;
  }
  const changed = !planning.mission || planning.mission.id !== data.id;
  planning.mission = data;
  planning.shownKey = key;
  planning.rejected = false;
  $("#mission-title").textContent = `${data.name} · ${data.id}`;
  if (changed && !flight.active) { closeReplay(); clearFlightView(); }
  await renderPlan(data);
  // The plan's status once its views are drawn: what it says is on screen.
  const state = $("#plan-state");
  state.innerHTML = "";
  state.append(badge(data.plan_ok, `${data.plan_status}${data.plan_ok ? ", verified" : ", not verified"}`));
  state.title = data.plan.message || "";
  if (!data.plan_ok && data.plan.message) state.append(` · ${data.plan.message}`);
  completeProgressLog(data.plan);
  $("#progress-log").hidden = true;  // the solver figures below sum it up
  refreshStale();
  emit(MISSION_SHOWN, data.id);
}

function finishPlanning() {
  planningEnded();
  planning.planning = false;
  updatePlanButtons();
  refreshStale();
}

/** The plan's views: trajectories fetched, every figure drawn, the fly view and slider.
 * @param {Mission} mission */
async function renderPlan(mission) {
  const plan = mission.plan;
  if (!plan || !plan.vehicles.length) return;
  // Show-sized fleets: fetched at a lower rate (scale.js), once when both rates meet.
  const horizon = plan.scenario.steps * plan.scenario.dt;
  const [viewRate, sepRate] = [10, 20].map((r) => trajectoryRate(r, plan.vehicles.length, horizon));
  const fetched = (/** @type {number} */ rate) => api("GET", `/api/missions/${mission.id}/trajectory?rate=${rate}`);
  const viewAnswer = fetched(viewRate);
  const [traj, sepTraj] = await Promise.all([viewAnswer, sepRate === viewRate ? viewAnswer : fetched(sepRate)]);
  if (!traj.ok || !sepTraj.ok) return;
  views.traj = traj.data;
  views.sepTraj = sepTraj.data;
  missionPlanShown();
  $("#empty-note").hidden = true;
  $("#fly-map").hidden = false;
  $("#flights").hidden = false;
  $("#fly-screen").classList.remove("no-plan");
  $("main").classList.add("has-plan");
  $("#plan-results").hidden = false;
  await renderFigures(plan, mission.plan_ok, traj.data, sepTraj.data);
  renderDownloads(mission);
  renderSequence(mission);
  await nextTask();
  drawFlyStatic();
  resetSlider();
}
