// fleetplan browser page: enter a mission, plan it, inspect the plan, fly exactly the plan on
// screen, watch the fleet, reopen and replay past flights, abort.
// Plain JavaScript modules, no build step; talks only to this service's /api (see /docs).
"use strict";

import { drawMoving, drawStatic, latLonText } from "./flyview.js";
import { batteryCell, gpsCell, healthCell, linkLevel } from "./health.js";
import { circleScenario, randomScenario, round2 } from "./presets.js";
import { measuredSeparation, minSeparation, sampleAt } from "./tracks.js";

const $ = (sel, root = document) => root.querySelector(sel);
const $$ = (sel, root = document) => Array.from(root.querySelectorAll(sel));
const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
const color = (i) => COLORS[i % COLORS.length];
const LIMIT_KEYS = ["position_min", "position_max", "velocity_max", "acceleration_max", "jerk_max"];
const PLOT_CONFIG = { responsive: true, displaylogo: false };
const TRAIL_POINTS = 1500;   // live trail kept per vehicle (5 Hz: 5 minutes)

const state = {
  mission: null,       // the mission document shown (GET /api/missions/{id})
  shownKey: null,      // the form (or "seq:" + the sequence text) as it was when that mission was shown
  planning: false,     // a plan request is being computed
  pendingKey: null,    // the form as sent with that request
  rejected: false,     // the last plan request was refused or failed
  stale: false,        // the results shown are not the form's mission
  presetName: null,    // name of the preset loaded, until the operator edits the form
  touched: false,      // the operator has typed in the form: nothing loads over it by itself
  traj: null,          // /trajectory?rate=10 for the views and the slider
  sep: null,           // {t, d} minimum pairwise separation over time (plan)
  measured: null,      // {t, d, label} measured separation of the flight replayed
  selected: 0,         // vehicle row the editor's top view places points for
  extra: {},           // scenario keys without inputs (separation_scale, ...), kept as loaded
  limitExtras: {},     // limits without inputs (thrust_min, thrust_max, body_rate_max)
  planStream: null,    // EventSource of the planning progress
  execution: null,     // id of the flight shown (live or replayed)
  flightActive: false, // that flight is under way
  paused: false,
  flightStream: null,  // EventSource of the flight telemetry
  live: null,          // last telemetry snapshot of the flight under way
  trails: {},          // id -> [[x, y]...] live positions so far
  replay: null,        // {id, vehicles: [{id, t: [...], position: [...]}]} flight replayed
  vehicles: [],        // last GET /api/vehicles rows (link, mode, battery, ...)
  fleet: null,         // fleet description (kind, vehicles, ids, flying, world_origin?)
  caps: { pause: false, resume: false, fleetCommands: false, vehicleCommands: false },
  flyTf: null,         // transform of the fly view
  playTimer: null,
  statuses: null,      // the service's status sets (GET /api/status `statuses`), never a copy
};

/** Whether a mission status has a role ("active": still planning, "failed") in the service's
 *  own status sets; false until they are known. */
function missionIs(status, role) {
  const sets = state.statuses && state.statuses.mission;
  return Boolean(sets && sets[role] && sets[role].includes(status));
}

// ------------------------------------------------------------------ HTTP

let tokenAsked = null;  // one token prompt shared by concurrent requests

async function api(method, url, body) {
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.body = JSON.stringify(body);
    init.headers["Content-Type"] = "application/json";
  }
  let response;
  try { response = await fetch(url, init); } catch (exc) {
    return { status: 0, ok: false, data: { reason: `service unreachable (${exc.message})` } };
  }
  if (response.status === 401) {  // the service wants an API token: ask once and keep it in
    tokenAsked ??= Promise.resolve(window.prompt("API token (operator or read-only):"))
      .then((token) => {           // a SameSite cookie, which EventSource sends too
        if (token) document.cookie = `fleetplan_token=${encodeURIComponent(token)}; path=/; SameSite=Strict`;
        return token;
      });
    if (await tokenAsked) response = await fetch(url, init);
    if (response.status === 401) tokenAsked = null;  // wrong token: ask again next time
  }
  const text = await response.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = { reason: text }; }
  return { status: response.status, ok: response.ok, data: data ?? {} };
}

/** The rows of a list answer: a bare array, or a page {items|executions|missions: [...]}. */
function rowsOf(data, key) {
  if (Array.isArray(data)) return data;
  if (data && Array.isArray(data[key])) return data[key];
  if (data && Array.isArray(data.items)) return data.items;
  return [];
}

// Append to a log list and keep the list (not the page) scrolled to its end.
function appendScrolled(list, item) {
  list.appendChild(item);
  list.scrollTop = list.scrollHeight;
}

const fmt = (x, digits = 3) => (x === null || x === undefined || Number.isNaN(x)) ? "–"
  : (typeof x === "number" ? Number(x.toFixed(digits)).toString() : String(x));
const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

function badge(good, text) {
  const span = document.createElement("span");
  span.className = good ? "ok" : "bad";
  span.textContent = text;
  return span;
}

// ------------------------------------------------------------------ form <-> scenario

function numberInput(field, value) {
  const input = document.createElement("input");
  input.type = "number";
  input.step = "any";
  input.dataset.field = field;
  if (value !== undefined && value !== null) input.value = value;
  return input;
}

function buildLimitRows() {
  for (const key of LIMIT_KEYS) {
    const row = $(`tr[data-limit="${key}"]`);
    for (let a = 0; a < 3; a++) {
      const td = document.createElement("td");
      td.appendChild(numberInput(`limits.${key}[${a}]`));
      row.appendChild(td);
    }
  }
}

function vehicleRows() { return $$("#vehicle-table tbody tr.vehicle"); }

function addVehicleRow(vehicle) {
  const tbody = $("#vehicle-table tbody");
  const index = vehicleRows().length;
  const tr = document.createElement("tr");
  tr.className = "vehicle";
  const idCell = document.createElement("td");
  const idInput = document.createElement("input");
  idInput.dataset.field = `vehicles[${index}].id`;
  idInput.value = vehicle.id;
  idInput.size = 6;
  idCell.appendChild(idInput);
  tr.appendChild(idCell);
  for (const which of ["start", "goal"]) {
    for (let a = 0; a < 3; a++) {
      const td = document.createElement("td");
      td.appendChild(numberInput(`vehicles[${index}].${which}[${a}]`, vehicle[which][a]));
      tr.appendChild(td);
    }
  }
  const rm = document.createElement("td");
  const button = document.createElement("button");
  button.type = "button";
  button.textContent = "✕";
  button.title = "remove this vehicle";
  button.className = "remove-vehicle";
  button.addEventListener("click", (ev) => { ev.stopPropagation(); removeVehicle(tr); });
  rm.appendChild(button);
  tr.appendChild(rm);
  tr.addEventListener("click", () => selectVehicle(vehicleRows().indexOf(tr)));
  tbody.appendChild(tr);
}

function renumberVehicles() {
  vehicleRows().forEach((tr, i) => {
    for (const input of $$("input", tr)) {
      input.dataset.field = input.dataset.field.replace(/^vehicles\[\d+\]/, `vehicles[${i}]`);
    }
  });
}

function removeVehicle(tr) {
  const next = tr.nextElementSibling;
  if (next && next.classList.contains("error-row")) next.remove();
  tr.remove();
  renumberVehicles();
  state.selected = Math.min(state.selected, vehicleRows().length - 1);
  formEdited();
}

function nextVehicleId() {
  const ids = new Set(vehicleRows().map((tr) => $("input", tr).value));
  let n = vehicleRows().length + 1;
  while (ids.has(`uav${n}`)) n++;
  return `uav${n}`;
}

function selectVehicle(index) {
  state.selected = index;
  vehicleRows().forEach((tr, i) => tr.classList.toggle("selected", i === index));
  drawTopView();
}

const readNumber = (input) => (input.value.trim() === "" ? null : Number(input.value));

function readScenario() {
  const value = (name) => $(`#f-${name}`).value;
  const limits = {};
  for (const key of LIMIT_KEYS) {
    const inputs = $$(`tr[data-limit="${key}"] input`);
    const v = inputs.map(readNumber);
    if (v.every((x) => x === null)) continue;  // optional bounds may be left empty
    limits[key] = v;
  }
  const vehicles = vehicleRows().map((tr) => {
    const inputs = $$("input", tr);
    const nums = inputs.slice(1).map(readNumber);
    return { id: inputs[0].value, start: nums.slice(0, 3), goal: nums.slice(3, 6) };
  });
  const scenario = {
    name: value("name"),
    dt: readNumber($("#f-dt")),
    steps: readNumber($("#f-steps")),
    min_separation: readNumber($("#f-min_separation")),
    limits,
    vehicles,
  };
  if (state.extra) Object.assign(scenario, state.extra);
  if (state.limitExtras) Object.assign(scenario.limits, state.limitExtras);
  return scenario;
}

function fillForm(scenario) {
  $("#f-name").value = scenario.name ?? "scenario";
  $("#f-dt").value = scenario.dt;
  $("#f-steps").value = scenario.steps;
  $("#f-min_separation").value = scenario.min_separation;
  for (const key of LIMIT_KEYS) {
    const v = scenario.limits[key];
    $$(`tr[data-limit="${key}"] input`).forEach((input, a) => { input.value = v ? v[a] : ""; });
  }
  // Keys the form has no inputs for travel along unchanged.
  state.extra = {};
  for (const key of ["separation_scale", "cost_threshold", "max_iterations"]) {
    if (scenario[key] !== undefined) state.extra[key] = scenario[key];
  }
  state.limitExtras = {};
  for (const key of ["thrust_min", "thrust_max", "body_rate_max"]) {
    if (scenario.limits[key] !== undefined) state.limitExtras[key] = scenario.limits[key];
  }
  $("#vehicle-table tbody").innerHTML = "";
  scenario.vehicles.forEach(addVehicleRow);
  clearErrors();
  selectVehicle(0);
}

// ------------------------------------------------------------------ presets

async function loadExampleList() {
  const { ok, data } = await api("GET", "/api/examples");
  if (!ok) return;
  const group = $("#preset-examples");
  for (const example of data) {
    const option = document.createElement("option");
    option.value = `example:${example.name}`;
    option.textContent = `${example.name} · ${example.vehicles} vehicles`;
    group.appendChild(option);
  }
  $("#preset").value = "example:paper-circle4";
  presetChosen();
}

// The vehicle count applies to the generated presets only: shown with them alone.
function presetChosen() {
  $("#preset-count-label").hidden = !$("#preset").value.startsWith("gen:");
}

// `auto`: the page's first preset, which must not land on a form the operator has touched.
async function loadPreset(auto = false) {
  const choice = $("#preset").value;
  const n = clamp(Math.round(Number($("#preset-count").value) || 8), 2, 128);
  let scenario = null;
  if (choice === "gen:circle") scenario = circleScenario(n);
  else if (choice === "gen:random") scenario = randomScenario(n);
  else {
    const { ok, data } = await api("GET", `/api/examples/${choice.slice(8)}`);
    if (!ok) return;
    scenario = data;
    if (auto && state.touched) return;
  }
  fillForm(scenario);
  state.presetName = $("#f-name").value;
  refreshStale();
}

// ------------------------------------------------------------------ top view

function workspace() {
  const read = (key) => $$(`tr[data-limit="${key}"] input`).map(readNumber);
  const lo = read("position_min"), hi = read("position_max");
  const okBox = [0, 1].every((a) => Number.isFinite(lo[a]) && Number.isFinite(hi[a]) && hi[a] > lo[a]);
  return okBox ? { lo, hi } : { lo: [0, 0, 0], hi: [10, 10, 3] };
}

function topViewTransform() {
  const { lo, hi } = workspace();
  const pad = 20, size = 400 - 2 * pad;
  const scale = size / Math.max(hi[0] - lo[0], hi[1] - lo[1]);
  return {
    lo, hi,
    toSvg: (x, y) => [pad + (x - lo[0]) * scale, 400 - pad - (y - lo[1]) * scale],
    toWorld: (sx, sy) => [lo[0] + (sx - pad) / scale, lo[1] + (400 - pad - sy) / scale],
  };
}

function svg(tag, attrs, parent) {
  const el = document.createElementNS("http://www.w3.org/2000/svg", tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  if (parent) parent.appendChild(el);
  return el;
}

function drawTopView() {
  const view = $("#top-view");
  view.innerHTML = "";
  const tf = topViewTransform();
  const [x0, y0] = tf.toSvg(tf.lo[0], tf.lo[1]);
  const [x1, y1] = tf.toSvg(tf.hi[0], tf.hi[1]);
  svg("rect", { x: x0, y: y1, width: x1 - x0, height: y0 - y1, fill: "#fff", stroke: "#9aa4af" }, view);
  svg("text", { x: x0, y: y0 + 14, "font-size": 10, fill: "#6b7480" }, view).textContent =
    `(${tf.lo[0]}, ${tf.lo[1]})`;
  svg("text", { x: x1, y: y1 - 4, "font-size": 10, fill: "#6b7480", "text-anchor": "end" }, view)
    .textContent = `(${tf.hi[0]}, ${tf.hi[1]}) m`;
  vehicleRows().forEach((tr, i) => {
    const v = $$("input", tr).slice(1).map(readNumber);
    const [sx, sy] = tf.toSvg(v[0], v[1]);
    const [gx, gy] = tf.toSvg(v[3], v[4]);
    if (![sx, sy, gx, gy].every(Number.isFinite)) return;
    const c = color(i), selected = i === state.selected;
    svg("line", { x1: sx, y1: sy, x2: gx, y2: gy, stroke: c, "stroke-dasharray": "4 3", "stroke-width": selected ? 2 : 1 }, view);
    svg("circle", { cx: sx, cy: sy, r: selected ? 6 : 4, fill: c }, view);
    svg("path", { d: `M${gx - 5},${gy - 5}L${gx + 5},${gy + 5}M${gx - 5},${gy + 5}L${gx + 5},${gy - 5}`, stroke: c, "stroke-width": selected ? 3 : 2 }, view);
    svg("text", { x: sx + 6, y: sy - 6, "font-size": 10, fill: c }, view).textContent = $("input", tr).value;
  });
}

function onTopViewClick(ev) {
  const view = $("#top-view");
  const box = view.getBoundingClientRect();
  const sx = ((ev.clientX - box.left) / box.width) * 400;
  const sy = ((ev.clientY - box.top) / box.height) * 400;
  const [x, y] = topViewTransform().toWorld(sx, sy).map(round2);
  if (vehicleRows().length === 0) {
    addVehicleRow({ id: nextVehicleId(), start: [x, y, 1], goal: [x, y, 1] });
    selectVehicle(0);
  }
  const which = $('input[name="place"]:checked').value;
  const tr = vehicleRows()[state.selected];
  const inputs = $$("input", tr).slice(1);
  const offset = which === "start" ? 0 : 3;
  inputs[offset].value = x;
  inputs[offset + 1].value = y;
  if (inputs[offset + 2].value === "") inputs[offset + 2].value = 1;
  // Start placed: the next click places this vehicle's goal.
  $(`input[name="place"][value="${which === "start" ? "goal" : "start"}"]`).checked = true;
  formEdited();
}

// ------------------------------------------------------------------ errors next to fields

function clearErrors() {
  $$("input.invalid").forEach((i) => { i.classList.remove("invalid"); i.title = ""; });
  $$(".field-error").forEach((d) => { d.textContent = ""; });
  $$("tr.error-row").forEach((r) => r.remove());
}

// The fields an error path names: "vehicles[2].goal" marks that vehicle's three goal inputs.
function inputsFor(path) {
  return $$("#scenario-form input[data-field]").filter((input) => {
    const f = input.dataset.field;
    return path && (f === path || f.startsWith(`${path}[`) || f.startsWith(`${path}.`) ||
                    path.startsWith(`${f}[`));
  });
}

// The operator edited `input`: the errors about that field no longer hold.
function clearErrorsFor(input) {
  const field = input.dataset && input.dataset.field;
  if (!field) return;
  for (const item of $$(".error-item")) {
    if (inputsFor(item.dataset.path).includes(input)) {
      for (const marked of inputsFor(item.dataset.path)) { marked.classList.remove("invalid"); marked.title = ""; }
      const row = item.closest("tr.error-row");
      item.remove();
      if (row && !$(".error-item", row)) row.remove();
    }
  }
  input.classList.remove("invalid");
  input.title = "";
  $("#form-error").textContent = "";
}

function errorItem(path, reason) {
  const div = document.createElement("div");
  div.className = "error-item";
  div.dataset.path = path;
  div.textContent = path ? `${path}: ${reason}` : reason;
  return div;
}

function showError(field, reason) {
  const path = field || "";
  for (const input of inputsFor(path)) { input.classList.add("invalid"); input.title = reason; }
  const vehicle = /^vehicles\[(\d+)\]/.exec(path);
  if (vehicle && vehicleRows()[Number(vehicle[1])]) {
    const tr = vehicleRows()[Number(vehicle[1])];
    let row = tr.nextElementSibling;
    if (!row || !row.classList.contains("error-row")) {
      row = document.createElement("tr");
      row.className = "error-row";
      const td = document.createElement("td");
      td.colSpan = 8;
      td.className = "vehicle-error";
      row.appendChild(td);
      tr.after(row);
    }
    row.firstChild.appendChild(errorItem(path, reason));
    return;
  }
  const head = path.split(/[.[]/)[0];
  const box = $$(".field-error[data-error-for]").find((d) => d.dataset.errorFor.split(" ").includes(head));
  (box || $("#form-error")).appendChild(errorItem(path, reason));
}

// ------------------------------------------------------------------ fly only what is shown

// The form as one string: equal strings, same mission.
const formKey = () => JSON.stringify(readScenario());
// The sequence input as a key ("seq:" + its text): a mission planned from it is stale once
// the text changes, whatever the form says.
const sequenceKey = () => `seq:${$("#sequence-json").value}`;
const currentKey = (shown) => (shown && shown.startsWith("seq:") ? sequenceKey() : formKey());

// Any change to the form (typed, clicked on the map, preset loaded, row added or removed).
function formEdited(ev) {
  const target = ev && ev.target;
  state.touched = true;  // typed, clicked on the map, a row added or removed
  if (target && target.dataset) clearErrorsFor(target);
  // A preset edited is a new mission: say so in its name, unless the operator named it.
  if (target !== $("#f-name") && state.presetName && $("#f-name").value === state.presetName) {
    $("#f-name").value = `${state.presetName}-edited`;
    state.presetName = null;
  }
  if (target === $("#f-name")) state.presetName = null;
  // "rejected (422)" described the form as it was: once edited, say what to do next.
  if (state.rejected && !state.planning && target) {
    $("#plan-state").textContent = $(".error-item") ? "fix the fields marked, then Plan" : "edited: press Plan";
  }
  drawTopView();
  refreshStale();
}

// Mark the results stale (and Fly disabled) unless they are the form's mission.
function refreshStale() {
  const shown = Boolean(state.mission && state.mission.plan);
  let why = "";
  if (shown && state.planning) why = "Planning the form's mission: the results below are the previous plan's.";
  else if (shown && state.rejected) why = "The last plan request was rejected: the results below are an older mission's and cannot be flown.";
  else if (shown && currentKey(state.shownKey) !== state.shownKey) why = state.shownKey.startsWith("seq:")
    ? "The sequence has changed since this plan: the results below are stale. Press Plan sequence to fly what it says."
    : "The form has changed since this plan: the results below are stale. Press Plan to fly what the form says.";
  state.stale = Boolean(why);
  $("#stale-banner").textContent = why;
  $("#stale-banner").hidden = !why;
  $("#fly-panel").classList.toggle("stale", state.stale);
  updateFlyButton();
}

// Which plan vehicle flies on which fleet vehicle; the ones missing.
function vehicleMapping() {
  const planIds = state.mission.plan.vehicles.map((v) => v.id);
  const fleet = state.fleet;
  if (!fleet || !fleet.vehicles) return { planIds, pairs: [], missing: planIds, spare: [] };
  if (fleet.kind === "mock") {
    // The mock fleet is set down under the plan's starts and takes the plan's ids.
    const n = Math.min(planIds.length, fleet.vehicles);
    return { planIds, pairs: planIds.slice(0, n).map((id, i) => [id, `mock ${i + 1}`]),
             missing: planIds.slice(n), spare: [] };
  }
  const ids = fleet.ids || [];
  return { planIds, pairs: planIds.filter((id) => ids.includes(id)).map((id) => [id, id]),
           missing: planIds.filter((id) => !ids.includes(id)),
           spare: ids.filter((id) => !planIds.includes(id)) };
}

function showMapping() {
  const box = $("#mapping");
  box.textContent = "";
  if (!state.mission || !state.mission.plan || !state.fleet) return;
  const m = vehicleMapping();
  box.append("plan → fleet: ");
  const list = document.createElement("span");
  list.id = "mapping-pairs";
  list.textContent = idList(m.pairs.map(([p, f]) => (p === f ? p : `${p}→${f}`))) || "none";
  box.append(list);
  if (m.missing.length) {
    const bad = badge(false, ` · not in the fleet: ${idList(m.missing)}`);
    bad.id = "mapping-missing";
    box.append(bad);
  }
  if (m.spare.length) box.append(` · idle: ${m.spare.join(", ")}`);
}

// A list of ids, shortened past a dozen ("a, b, … and 30 more").
function idList(ids, max = 12) {
  return ids.length <= max ? ids.join(", ") : `${ids.slice(0, max).join(", ")}, … and ${ids.length - max} more`;
}

// Why Fly is disabled now, or null if the mission on screen can fly.
function flyBlocker() {
  if (!state.mission || !state.mission.plan) return "plan a mission first";
  if (state.planning) return "planning…";
  if (state.rejected) return "the last plan request was rejected: fix the form and plan again";
  if (state.stale) return "the form has changed: press Plan to fly what it says";
  if (!state.mission.plan_ok) return "the plan is not verified: it cannot be flown";
  if (state.flightActive) return "a flight is under way";
  if (!state.fleet || !state.fleet.vehicles) return "no fleet configured";
  if (state.fleet.flying) return `flight ${state.fleet.flying} is under way`;
  const missing = vehicleMapping().missing;
  if (missing.length) return `${missing.length} plan vehicle${missing.length > 1 ? "s are" : " is"} not in the fleet`;
  return null;
}

function updateFlyButton() {
  const why = flyBlocker();
  $("#fly-button").disabled = Boolean(why);
  $("#fly-reason").textContent = why || "";
  showMapping();
  updateCommandButtons();
}

// ------------------------------------------------------------------ planning

async function submitPlan(ev) {
  ev.preventDefault();
  clearErrors();
  if (state.planStream) { state.planStream.close(); state.planStream = null; }
  const scenario = readScenario();
  state.planning = true;
  state.rejected = false;
  state.pendingKey = JSON.stringify(scenario);
  refreshStale();
  $("#plan-button").disabled = true;
  $("#plan-state").textContent = "submitting…";
  $("#progress-log").innerHTML = "";
  $("#progress-log").hidden = false;
  const { status, data } = await api("POST", "/api/missions?wait=0", scenario);
  if (status !== 201 && status !== 202) {
    state.planning = false;
    state.rejected = true;
    $("#plan-button").disabled = false;
    $("#plan-state").textContent = "";
    $("#plan-state").append(badge(false, `rejected (${status}): see the fields marked`));
    const errors = (data && data.errors && data.errors.length) ? data.errors
      : [{ field: data && data.field, reason: (data && data.reason) || "error" }];
    for (const e of errors) showError(e.field, e.reason);
    refreshStale();
    return;
  }
  followPlanning(data, state.pendingKey);
}

// Plan the sequence JSON pasted or loaded: one mission like a scenario's, legs in parallel.
async function submitSequence() {
  clearErrors();
  const box = $("#sequence-error");
  let body;
  try { body = JSON.parse($("#sequence-json").value); } catch (exc) {
    box.append(errorItem("sequence", `not valid JSON: ${exc.message}`));
    return;
  }
  if (!body || typeof body !== "object" || Array.isArray(body) || !("formations" in body)) {
    box.append(errorItem("sequence", "must be a JSON object with formations"));
    return;
  }
  if (state.planStream) { state.planStream.close(); state.planStream = null; }
  state.planning = true;
  state.rejected = false;
  state.pendingKey = sequenceKey();
  refreshStale();
  $("#plan-button").disabled = true;
  $("#sequence-plan").disabled = true;
  $("#plan-state").textContent = "submitting…";
  $("#progress-log").innerHTML = "";
  $("#progress-log").hidden = false;
  const { status, data } = await api("POST", "/api/missions?wait=0", body);
  $("#sequence-plan").disabled = false;
  if (status !== 201 && status !== 202) {
    state.planning = false;
    state.rejected = true;
    $("#plan-button").disabled = false;
    $("#plan-state").textContent = "";
    $("#plan-state").append(badge(false, `rejected (${status}): see the sequence errors`));
    const errors = (data && data.errors && data.errors.length) ? data.errors
      : [{ field: data && data.field, reason: (data && data.reason) || "error" }];
    for (const e of errors) box.append(errorItem(e.field || "", e.reason));
    refreshStale();
    return;
  }
  followPlanning(data, state.pendingKey);
}

async function loadSequenceFile(ev) {
  const file = ev.target.files && ev.target.files[0];
  if (!file) return;
  $("#sequence-json").value = await file.text();
  $("#sequence-panel").open = true;
  refreshStale();
}

// A sequence's plan: its formations and timeline, and its show-tool CSVs to download.
function renderSequence(mission) {
  const info = $("#sequence-info");
  const seq = mission.plan.sequence;
  info.innerHTML = "";
  info.hidden = !seq;
  if (!seq) return;
  const names = seq.formations.map((f) => f.name).join(" → ");
  const legs = seq.legs.map((l) => `${l.status}, ${l.iterations} SCP iterations`).join("; ");
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

function followPlanning(mission, key) {
  $("#plan-state").textContent = "planning…";
  if (!missionIs(mission.status, "active")) { showMission(mission.id, key); return; }
  const source = new EventSource(`/api/missions/${mission.id}/events`);
  state.planStream = source;
  source.addEventListener("iteration", (ev) => {
    const r = JSON.parse(ev.data);
    const li = document.createElement("li");
    const leg = (r.leg === undefined || r.leg === null) ? "" : `leg ${r.leg}, `;
    li.textContent = `${leg}iteration ${r.iteration}: cost ${fmt(r.cost, 2)}` +
      (r.cost_change === null ? "" : ` (Δ ${fmt(r.cost_change, 3)})`) +
      `, ${r.separation_rows} separation rows, ${r.qp_solves} QP solves, ${fmt(r.seconds, 3)} s`;
    appendScrolled($("#progress-log"), li);
    $("#plan-state").textContent = `planning… ${leg}iteration ${r.iteration}`;
  });
  source.addEventListener("done", () => { source.close(); state.planStream = null; showMission(mission.id, key); });
  source.onerror = () => {  // stream lost: fall back to polling the mission
    source.close();
    state.planStream = null;
    setTimeout(() => showMission(mission.id, key), 1000);
  };
}

// Show a mission's plan. `key` is the form it was planned from (or loaded into).
async function showMission(id, key) {
  const { ok, data } = await api("GET", `/api/missions/${id}`);
  $("#plan-button").disabled = false;
  if (!ok) { $("#plan-state").textContent = data.reason; state.planning = false; refreshStale(); return; }
  if (missionIs(data.status, "active")) { followPlanning(data, key); return; }
  state.planning = false;
  refreshMissionList();
  $("#plan-state").innerHTML = "";
  if (missionIs(data.status, "failed") || !data.plan) {
    state.rejected = true;
    $("#plan-state").append(badge(false, `planning failed: ${data.error ? data.error.reason : data.status}`));
    if (data.error && data.error.field) showError(data.error.field, data.error.reason);
    refreshStale();
    return;
  }
  const changed = !state.mission || state.mission.id !== data.id;
  state.mission = data;
  state.shownKey = key;
  state.rejected = false;
  $("#mission-title").textContent = `${data.name} · ${data.id}`;
  $("#plan-state").append(badge(data.plan_ok, `${data.plan_status}${data.plan_ok ? ", verified" : ", not verified"}`));
  $("#plan-state").title = data.plan.message || "";
  if (!data.plan_ok && data.plan.message) $("#plan-state").append(` · ${data.plan.message}`);
  if (changed && !state.flightActive) { closeReplay(); clearFlightView(); }
  $("#progress-log").hidden = true;  // the solver figures below sum it up
  await renderPlan(data);
  refreshStale();
  loadFlights(data.id);
}

// ------------------------------------------------------------------ plan views

async function renderPlan(mission) {
  const plan = mission.plan;
  if (!plan.vehicles.length) return;
  const [traj, sepTraj] = await Promise.all([
    api("GET", `/api/missions/${mission.id}/trajectory?rate=10`),
    api("GET", `/api/missions/${mission.id}/trajectory?rate=20`),
  ]);
  if (!traj.ok || !sepTraj.ok) return;
  state.traj = traj.data;
  state.sepTraj = sepTraj.data;
  $("#empty-note").hidden = true;
  $("#fly-map").hidden = false;
  $("#flights").hidden = false;
  $("#fly-screen").classList.remove("no-plan");
  $("main").classList.add("has-plan");
  $("#plan-results").hidden = false;
  renderSummary(plan, mission.plan_ok);
  renderSequence(mission);
  render3d(plan, traj.data);
  renderSeparation(plan, sepTraj.data);
  renderSpeed(sepTraj.data);
  renderThrust(plan);
  drawFlyStatic();
  const slider = $("#time-slider");
  slider.max = traj.data.t.length - 1;
  slider.value = 0;
  setTime(0);
}

function render3d(plan, traj) {
  const many = traj.vehicles.length > 16;
  const lines = traj.vehicles.map((v, i) => ({
    type: "scatter3d", mode: "lines", name: v.id,
    x: v.position.map((p) => p[0]), y: v.position.map((p) => p[1]), z: v.position.map((p) => p[2]),
    line: { color: color(i), width: 3 }, hoverinfo: "name",
  }));
  const now = {
    type: "scatter3d", mode: "markers", name: "planned now", showlegend: false,
    x: [], y: [], z: [], text: traj.vehicles.map((v) => v.id), hoverinfo: "text",
    marker: { size: 4, color: traj.vehicles.map((_, i) => color(i)), opacity: 0.5 },
  };
  const flown = {
    type: "scatter3d", mode: "markers+text", name: "flown",
    x: [], y: [], z: [], text: [], hoverinfo: "text", textposition: "top center",
    marker: { size: 6, symbol: "diamond", color: [] },
  };
  const s = plan.scenario.limits;
  const layout = {
    margin: { l: 0, r: 0, t: 24, b: 0 }, showlegend: !many,
    title: { text: "trajectories (world frame, z up); rings: plan now, diamonds: flown", font: { size: 13 } },
    scene: {
      aspectmode: "data",
      xaxis: { title: { text: "x (m)" }, range: [s.position_min[0], s.position_max[0]] },
      yaxis: { title: { text: "y (m)" }, range: [s.position_min[1], s.position_max[1]] },
      zaxis: { title: { text: "z (m)" }, range: [s.position_min[2], s.position_max[2]] },
    },
    uirevision: "keep",
  };
  Plotly.react("plot3d", [...lines, now, flown], layout, PLOT_CONFIG);
}

function row(table, label, value, good) {
  const tr = document.createElement("tr");
  const a = document.createElement("td"), b = document.createElement("td");
  a.textContent = label;
  if (good === undefined) b.textContent = value; else b.append(badge(good, value));
  tr.append(a, b);
  table.appendChild(tr);
  return b;
}

function renderSummary(plan, planOk) {
  const v = plan.verification || {};
  const R = plan.scenario.min_separation;
  const ver = $("#verification");
  ver.innerHTML = "<caption>verification</caption>";
  row(ver, "status", `${plan.status}${plan.message ? ": " + plan.message : ""}`, planOk);
  const cell = row(ver, "min separation (continuous)", `${fmt(v.min_separation_continuous)} m (R = ${R} m)`, v.separated);
  cell.id = "min-separation-value";
  cell.dataset.value = v.min_separation_continuous;
  if (v.closest_pair && v.closest_pair.length) row(ver, "closest pair", `${v.closest_pair.join(" – ")} at t = ${fmt(v.closest_time, 2)} s`);
  row(ver, "within bounds", v.within_bounds ? "yes" : "no", v.within_bounds);
  row(ver, "flyable", v.flyable ? "yes" : "no", v.flyable);
  row(ver, "thrust range", v.thrust_range ? `${fmt(v.thrust_range[0], 3)} – ${fmt(v.thrust_range[1], 3)} m/s²` : "–");
  row(ver, "body-rate peak", `${fmt(v.body_rate_peak, 2)} rad/s`);
  const worst = Object.entries(v.max_violation || {}).sort((a, b) => (b[1] ?? 0) - (a[1] ?? 0))[0];
  if (worst) row(ver, "largest bound excess", `${worst[0]}: ${fmt(worst[1], 6)}`);
  const sol = $("#solver-figures");
  sol.innerHTML = "<caption>solver</caption>";
  const its = plan.iterations || [];
  row(sol, "solver", plan.solver);
  row(sol, "SCP iterations", its.length ? String(its[its.length - 1].iteration) : "–");
  row(sol, "final cost", its.length ? fmt(its[its.length - 1].cost, 2) : "–");
  row(sol, "QP solves", String(its.reduce((s, r) => s + r.qp_solves, 0)));
  row(sol, "separation rows (last)", its.length ? String(its[its.length - 1].separation_rows) : "–");
  row(sol, "planning time", `${fmt(plan.timing.total_s, 3)} s`);
  row(sol, "first QP", `${fmt(plan.timing.first_qp_s, 3)} s`);
  row(sol, "vehicles × steps", `${plan.vehicles.length} × ${plan.scenario.steps} (dt ${plan.scenario.dt} s)`);
}

function renderSeparation(plan, traj) {
  const R = plan.scenario.min_separation;
  if (traj.vehicles.length < 2) { Plotly.purge("separation-plot"); return; }
  state.sep = minSeparation(plan, traj);
  const low = Math.min(...state.sep.d);
  const traces = [
    { x: state.sep.t, y: state.sep.d, mode: "lines", name: "min pairwise distance", line: { color: "#1f6feb" } },
    { x: [0, traj.t[traj.t.length - 1]], y: [R, R], mode: "lines", name: `R = ${R} m`, line: { color: "#c62828", dash: "dash" } },
  ];
  if (state.measured) {
    traces.push({ x: state.measured.t, y: state.measured.d, mode: "lines", name: state.measured.label,
                  line: { color: "#2e7d32" } });
  }
  Plotly.react("separation-plot", traces, {
    title: { text: `minimum pairwise separation: ${low.toFixed(3)} m (R = ${R} m)`, font: { size: 13 } },
    margin: { l: 50, r: 10, t: 30, b: 40 }, xaxis: { title: { text: "t (s)" } },
    yaxis: { title: { text: "m" }, rangemode: "tozero" }, legend: { orientation: "h" },
  }, PLOT_CONFIG);
  $("#separation-plot").dataset.minimum = low;
}

function renderSpeed(traj) {
  Plotly.react("speed-plot", traj.vehicles.map((v, i) => ({
    x: traj.t, y: v.velocity.map((u) => Math.hypot(u[0], u[1], u[2])), mode: "lines", name: v.id,
    line: { color: color(i), width: 1 },
  })), {
    title: { text: "speed per vehicle", font: { size: 13 } }, showlegend: false,
    margin: { l: 50, r: 10, t: 30, b: 40 }, xaxis: { title: { text: "t (s)" } }, yaxis: { title: { text: "m/s" } },
  }, PLOT_CONFIG);
}

function renderThrust(plan) {
  const lim = plan.scenario.limits;
  const end = plan.scenario.steps * plan.scenario.dt;
  const traces = plan.vehicles.map((v, i) => ({
    x: v.t.slice(0, -1), y: v.thrust, mode: "lines", name: v.id, line: { color: color(i), width: 1, shape: "hv" },
  }));
  for (const [key, label] of [["thrust_min", "min"], ["thrust_max", "max"]]) {
    if (lim[key] !== undefined) traces.push({ x: [0, end], y: [lim[key], lim[key]], mode: "lines", name: `thrust ${label}`, line: { color: "#c62828", dash: "dot" } });
  }
  Plotly.react("thrust-plot", traces, {
    title: { text: "mass-normalised thrust per vehicle", font: { size: 13 } }, showlegend: false,
    margin: { l: 50, r: 10, t: 30, b: 40 }, xaxis: { title: { text: "t (s)" } }, yaxis: { title: { text: "m/s²" } },
  }, PLOT_CONFIG);
}

// ------------------------------------------------------------------ the fly screen

const colorOf = (id) => {
  const i = state.traj ? state.traj.vehicles.findIndex((v) => v.id === id) : -1;
  return i >= 0 ? color(i) : "#1d232b";
};
const origin = () => (state.fleet && state.fleet.world_origin) || null;

function drawFlyStatic() {
  if (!state.traj || !state.mission) return;
  const lim = state.mission.plan.scenario.limits;
  state.flyTf = drawStatic($("#fly-view"), {
    lo: lim.position_min, hi: lim.position_max, origin: origin(),
    paths: state.traj.vehicles.map((v, i) => ({ id: v.id, color: color(i), points: v.position.map((p) => [p[0], p[1]]) })),
  });
  const o = origin();
  $("#geo-label").textContent = o
    ? `world origin ${latLonText(o)}, ${fmt(o.alt, 1)} m AMSL · x east, y north`
    : "x east, y north (m); no geodetic origin in the fleet file";
  drawFlyMoving();
}

// Where each vehicle is: the flight under way, or the replayed one at the slider's time.
function actualVehicles() {
  if (state.replay) {
    const t = sliderTime();
    return state.replay.vehicles.map((v) => ({
      id: v.id, color: colorOf(v.id), position: sampleAt(v.t, v.position, t),
      trail: v.position.filter((_, i) => v.t[i] <= t).map((p) => [p[0], p[1]]),
    }));
  }
  if (!state.live) return [];
  return state.live.vehicles.map((v) => ({
    id: v.id, color: colorOf(v.id), position: v.position, velocity: v.velocity,
    trail: state.trails[v.id], alert: Boolean(v.fault) || linkLevel(v) === "bad",
  }));
}

function drawFlyMoving() {
  if (!state.flyTf || !state.traj) return;
  const k = Number($("#time-slider").value);
  const planned = state.traj.vehicles.map((v, i) => ({ id: v.id, color: color(i), position: v.position[k] }));
  const vehicles = actualVehicles();
  drawMoving($("#fly-view"), state.flyTf, { planned, vehicles });
  const shown = vehicles.filter((v) => v.position);
  if ($("#plot3d").data) {
    Plotly.restyle("plot3d", {
      x: [shown.map((v) => v.position[0])], y: [shown.map((v) => v.position[1])],
      z: [shown.map((v) => v.position[2])], text: [shown.map((v) => v.id)],
      "marker.color": [shown.map((v) => v.color)],
    }, [state.traj.vehicles.length + 1]);
  }
}

function clearFlightView() {
  state.live = null;
  state.trails = {};
  $("#flight-phase").textContent = "";
  $("#flight-progress").value = 0;
}

const sliderTime = () => (state.traj ? state.traj.t[Number($("#time-slider").value)] : 0);
const horizon = () => (state.traj ? state.traj.t[state.traj.t.length - 1] : 0);

function setTime(k) {
  const traj = state.traj;
  if (!traj) return;
  const index = traj.vehicles.length;  // the "planned now" trace follows the lines
  const pos = traj.vehicles.map((v) => v.position[k]);
  if ($("#plot3d").data) {
    Plotly.restyle("plot3d", { x: [pos.map((p) => p[0])], y: [pos.map((p) => p[1])], z: [pos.map((p) => p[2])] }, [index]);
  }
  drawFlyMoving();
  showClock();
}

// The time label and the progress bar: the flight's progress while one flies, else the slider.
function showClock() {
  const t = sliderTime(), end = horizon();
  const live = state.flightActive && state.live;
  const mt = live ? state.live.mission_time : null;
  let text;
  let fraction = end > 0 ? t / end : 0;
  if (live) {
    if (mt === null || mt === undefined) {
      text = `${state.live.phase} · plan not started`;
      fraction = 0;
    } else if (mt <= end) {
      text = `${state.live.phase} · t = ${mt.toFixed(1)} s of ${end.toFixed(1)} s`;
      fraction = mt / end;
    } else {
      text = `${state.live.phase} · plan flown (${end.toFixed(1)} s of ${end.toFixed(1)} s), ` +
        `+${(mt - end).toFixed(1)} s after its end`;
      fraction = 1;
    }
    if (mt !== null && mt !== undefined && Math.abs(Math.min(mt, end) - t) > 0.15) {
      text += ` · viewing t = ${t.toFixed(1)} s`;
    }
  } else if (state.replay) {
    text = `replay of flight ${state.replay.id} · t = ${t.toFixed(1)} s of ${end.toFixed(1)} s`;
  } else {
    text = `plan · t = ${t.toFixed(1)} s of ${end.toFixed(1)} s`;
  }
  $("#time-label").textContent = text;
  $("#flight-progress").value = Math.round(clamp(fraction, 0, 1) * 1000);
}

function togglePlay() {
  if (!state.traj) return;
  if (state.playTimer) { stopPlay(); return; }
  $("#play").textContent = "⏸";
  $("#follow").checked = false;
  const slider = $("#time-slider");
  state.playTimer = setInterval(() => {
    let k = Number(slider.value) + 1;
    if (k > Number(slider.max)) k = 0;
    slider.value = k;
    setTime(k);
  }, 1000 / state.traj.rate);
}

function stopPlay() {
  clearInterval(state.playTimer);
  state.playTimer = null;
  $("#play").textContent = "▶";
}

// ------------------------------------------------------------------ fleet table

const OPTIONAL_COLUMNS = [["battery", "battery", batteryCell], ["gps", "GPS", gpsCell]];

// Rows: the flight's telemetry (positions 5 per second) merged with GET /api/vehicles
// (battery, GPS, health, link when the service reports them).
function showVehicleTable() {
  const byId = new Map(state.vehicles.map((v) => [v.id, v]));
  const rows = state.live && state.flightActive
    ? state.live.vehicles.map((v) => ({ ...(byId.get(v.id) || {}), ...v }))
    : state.vehicles;
  const optional = OPTIONAL_COLUMNS.filter(([key]) => rows.some((v) => v[key] !== undefined && v[key] !== null));
  const health = rows.some((v) => v.health !== undefined && v.health !== null);
  const actions = state.caps.vehicleCommands;
  const heads = ["vehicle", "link", "mode", "armed", "alt", ...optional.map((c) => c[1]),
                 ...(health ? ["health"] : []), "phase", ...(actions ? [""] : [])];
  const thead = $("#vehicle-state thead");
  const headHtml = `<tr>${heads.map((h) => `<th>${h}</th>`).join("")}</tr>`;
  if (thead.innerHTML !== headHtml) thead.innerHTML = headHtml;
  const tbody = $("#vehicle-state tbody");
  tbody.innerHTML = "";
  for (const v of rows) {
    const tr = document.createElement("tr");
    tr.dataset.id = v.id;
    const cell = (text, level, key) => {
      const td = document.createElement("td");
      td.textContent = text;
      if (level) td.className = `cell-${level}`;
      if (key) td.dataset.key = key;
      tr.appendChild(td);
      return td;
    };
    const name = cell("", "", "id");
    const dot = document.createElement("span");
    dot.className = "swatch";
    dot.style.background = colorOf(v.id);
    name.append(dot, v.id);
    const age = v.heartbeat_age;
    const link = cell(age === null || age === undefined ? "no link" : `${age.toFixed(1)} s`, linkLevel(v), "link");
    link.title = `heartbeat age${v.link ? ` (${v.link})` : ""}`;
    // PX4's AUTO.* modes by their short names (LOITER, LAND, RTL): the full name in the title.
    cell(v.mode ? v.mode.replace(/^AUTO\./, "") : "–", v.mode ? "" : "warn", "mode").title = v.mode ?? "";
    cell(v.armed === null || v.armed === undefined ? "–" : (v.armed ? "armed" : "no"),
      v.armed ? "armed" : "", "armed").title = v.armed ? "armed" : "disarmed";
    const alt = v.position ? `${v.position[2].toFixed(1)} m` : "–";
    cell(alt, "", "alt").title = v.position ? `world ${v.position.map((x) => x.toFixed(2)).join(", ")} m` +
      (v.tracking_error === null || v.tracking_error === undefined ? "" : ` · ±${v.tracking_error.toFixed(2)} m from plan`) : "";
    for (const [key, , render] of optional) {
      const [text, level, title] = render(v[key]);
      cell(text, level, key).title = title;
    }
    if (health) { const [text, level] = healthCell(v.health, v.fault); cell(text, level, "health"); }
    cell(v.phase ?? "idle", v.fault ? "bad" : "", "phase").title = v.fault || "";
    if (actions) {
      const td = cell("", "", "actions");
      for (const [command, label] of [["hold", "H"], ["land", "L"], ["rtl", "R"]]) {
        const b = document.createElement("button");
        b.type = "button";
        b.className = "mini";
        b.textContent = label;
        b.title = `${command} ${v.id}`;
        b.dataset.vehicleCommand = command;
        b.addEventListener("click", () => vehicleCommand(v.id, command));
        td.appendChild(b);
      }
    }
    if (v.fault) tr.className = "bad";
    tbody.appendChild(tr);
  }
}

// ------------------------------------------------------------------ commands

// Which of the planned control endpoints this service has, from its OpenAPI description:
// buttons for the others stay hidden (nothing is sent to find out).
async function loadCapabilities() {
  const { ok, data } = await api("GET", "/openapi.json");
  if (!ok || !data.paths) return;
  const posts = new Set(Object.entries(data.paths).filter(([, ops]) => ops && ops.post)
    .map(([path]) => path.replace(/\{[^}]+\}/g, "{}")));
  state.caps = {
    pause: posts.has("/api/executions/{}/pause"),
    resume: posts.has("/api/executions/{}/resume"),
    fleetCommands: posts.has("/api/fleet/commands"),
    vehicleCommands: posts.has("/api/vehicles/{}/commands"),
  };
  for (const el of $$("[data-cap]")) el.hidden = !state.caps[el.dataset.cap];
  updateCommandButtons();
  showVehicleTable();
}

function updateCommandButtons() {
  $("#pause-button").disabled = !(state.flightActive && !state.paused);
  $("#resume-button").disabled = !(state.flightActive && state.paused);
  const fleet = Boolean(state.fleet && state.fleet.vehicles);
  for (const b of $$(".fleet-commands button")) b.disabled = !fleet;
}

// A route this service lacks (404/405 without a field): hide its button for good.
function unavailable(response) {
  return (response.status === 404 || response.status === 405) && !(response.data && response.data.field);
}

function commandResult(text, good) {
  const el = $("#command-result");
  el.textContent = text;
  el.className = good ? "ok" : "bad";
}

async function pauseOrResume(which) {
  if (!state.execution) return;
  const r = await api("POST", `/api/executions/${state.execution}/${which}`);
  if (unavailable(r)) { state.caps[which] = false; $(`#${which}-button`).hidden = true; commandResult(`${which}: not available on this service`, false); return; }
  if (!r.ok) { commandResult(`${which} refused (${r.status}): ${r.data.reason ?? ""}`, false); return; }
  state.paused = which === "pause";
  commandResult(`${which}d`, true);
  updateCommandButtons();
}

async function fleetCommand(command) {
  const ids = (state.fleet && state.fleet.ids) || state.vehicles.map((v) => v.id);
  const r = await api("POST", "/api/fleet/commands", { command, vehicles: ids, confirm: true });
  if (unavailable(r)) { state.caps.fleetCommands = false; $(".fleet-commands").hidden = true; commandResult(`${command}: not available on this service`, false); return; }
  commandResult(r.ok ? `${command} sent to ${ids.length} vehicles` : `${command} refused (${r.status}): ${r.data.reason ?? ""}`, r.ok);
}

async function vehicleCommand(id, command) {
  const r = await api("POST", `/api/vehicles/${encodeURIComponent(id)}/commands`, { command, confirm: true });
  if (unavailable(r)) { state.caps.vehicleCommands = false; showVehicleTable(); commandResult(`${command}: not available on this service`, false); return; }
  commandResult(r.ok ? `${command} sent to ${id}` : `${command} ${id} refused (${r.status}): ${r.data.reason ?? ""}`, r.ok);
}

// ------------------------------------------------------------------ flying

async function fly() {
  if (flyBlocker()) return;  // the button is disabled then; a stale click does nothing
  const mission = state.mission;
  $("#fly-button").disabled = true;
  $("#event-log").innerHTML = "";
  $("#flight-summary").textContent = "";
  const { status, data } = await api("POST", `/api/missions/${mission.id}/executions`);
  if (status !== 201) {
    $("#execution-status").textContent = `refused (${status}): ${data.reason}`;
    $("#execution-status").className = "bad";
    updateFlyButton();
    return;
  }
  $("#follow").checked = true;
  followExecution(data);
  loadFlights(mission.id);
  refreshMissionList();
  $("#fly-screen").scrollIntoView({ block: "nearest" });
}

function followExecution(execution) {
  if (state.flightStream) state.flightStream.close();
  closeReplay();
  if (state.execution !== execution.id) clearFlightView();
  state.execution = execution.id;
  state.flightActive = true;
  state.paused = Boolean(execution.paused);
  setExecutionStatus(execution.status);
  updateFlyButton();
  if (!state.mission || state.mission.id !== execution.mission_id) {
    showFlownMission(execution.mission_id);  // flown from elsewhere: show its plan
  }
  const source = new EventSource(`/api/executions/${execution.id}/events`);
  state.flightStream = source;
  source.addEventListener("telemetry", (ev) => showTelemetry(JSON.parse(ev.data)));
  source.addEventListener("event", (ev) => logEvent(JSON.parse(ev.data)));
  source.addEventListener("status", (ev) => {
    setExecutionStatus(JSON.parse(ev.data).status);
    if (state.mission) loadFlights(state.mission.id);  // its badges follow
    refreshMissionList();
  });
  source.addEventListener("done", (ev) => {
    source.close();
    state.flightStream = null;
    const done = JSON.parse(ev.data);
    flightEnded(done.status, done);
  });
  source.onerror = () => {  // stream lost: poll the execution instead
    source.close();
    state.flightStream = null;
    setTimeout(() => pollExecution(execution.id), 1000);
  };
}

function flightEnded(status, done) {
  state.flightActive = false;
  state.paused = false;
  setExecutionStatus(status, Boolean(done && done.summary && done.summary.completed));
  showFlightSummary(done);
  showClock();
  showVehicleTable();
  updateFlyButton();
  refreshMissionList();
  if (state.mission) loadFlights(state.mission.id);
}

// Show the plan of a flight started elsewhere. A page with nothing planned yet takes that
// mission into its form too; otherwise the operator's form is kept (and reads as stale).
async function showFlownMission(id) {
  if (state.mission || state.planning || state.touched) { showMission(id, null); return; }
  const got = await api("GET", `/api/missions/${id}`);
  if (!got.ok) return;
  fillForm(got.data.scenario);
  state.presetName = null;
  showMission(id, formKey());
}

// A flight is under way while it has no finish time.
const isLive = (execution) => !execution.finished_at;

async function pollExecution(id) {
  const { ok, data } = await api("GET", `/api/executions/${id}`);
  if (!ok) return;
  if (isLive(data)) followExecution(data);
  else { state.execution = id; flightEnded(data.status, data); }
}

// `good`: the finished flight completed (from its summary); undefined while it flies.
function setExecutionStatus(status, good) {
  const el = $("#execution-status");
  el.textContent = `flight ${state.execution}: ${status}`;
  el.dataset.status = status;
  el.className = state.flightActive || good === undefined ? "" : (good ? "ok" : "bad");
  $("#flight-banner").textContent = state.flightActive ? `✈ ${status}` : "";
  $("#flight-banner").title = state.flightActive ? `flight ${state.execution}` : "";
}

function showTelemetry(t) {
  state.live = t;
  for (const v of t.vehicles) {
    if (!v.position) continue;
    const trail = state.trails[v.id] || (state.trails[v.id] = []);
    trail.push([v.position[0], v.position[1]]);
    if (trail.length > TRAIL_POINTS) trail.splice(0, trail.length - TRAIL_POINTS);
  }
  // Draw once per frame at most: a slow machine skips frames instead of falling behind.
  if (!state.drawPending) {
    state.drawPending = true;
    requestAnimationFrame(() => { state.drawPending = false; drawTelemetry(state.live); });
  }
}

function drawTelemetry(t) {
  if (!t) return;
  showVehicleTable();
  const sep = t.min_separation_live === null ? "" : `closest pair now ${t.min_separation_live.toFixed(2)} m`;
  $("#flight-phase").textContent = sep;
  if ($("#follow").checked && state.traj && t.mission_time !== null && t.mission_time !== undefined) {
    const slider = $("#time-slider");
    slider.value = clamp(Math.round(t.mission_time * state.traj.rate), 0, Number(slider.max));
    setTime(Number(slider.value));
  } else {
    drawFlyMoving();
    showClock();
  }
}

function logEvent(e) {
  const li = document.createElement("li");
  li.textContent = `${fmt(e.t, 2)} s ${e.vehicle ? e.vehicle + ": " : ""}${e.kind} ${e.detail ?? ""}`;
  appendScrolled($("#event-log"), li);
}

function showFlightSummary(done) {
  const s = done.summary;
  const box = $("#flight-summary");
  box.textContent = "";
  if (done.error) box.append(badge(false, `${done.error} `));
  if (!s) return;
  box.append(badge(Boolean(s.completed), `completed: ${s.completed ? "yes" : "no"}`),
    ` · goal error max ${fmt(s.goal_error_max)} m · tracking error max ${fmt(s.tracking_error_max)} m · ` +
    `measured min separation ${fmt(s.min_separation_measured)} m · setpoints ${fmt(s.setpoint_rate_hz, 1)} Hz, ` +
    `jitter p99 ${fmt(s.jitter_p99_ms, 2)} ms`);
}

async function abortAll() {
  // Abort the flight shown and any other one under way: this button must always work.
  const { ok, data } = await api("GET", "/api/executions?active=true");
  const ids = new Set(ok ? rowsOf(data, "executions").map((e) => e.id) : []);
  if (state.execution && state.flightActive) ids.add(state.execution);
  if (state.fleet && state.fleet.flying) ids.add(state.fleet.flying);
  if (!ids.size) { $("#flight-banner").textContent = "nothing is flying"; return; }
  for (const id of ids) {
    const r = await api("POST", `/api/executions/${id}/abort`, { action: "land" });
    if (r.ok && id === state.execution) setExecutionStatus(r.data.status);
  }
}

// ------------------------------------------------------------------ flight history

// A status badge for a flight: green completed, neutral while flying, red otherwise.
function flightBadge(execution) {
  const span = document.createElement("span");
  span.className = `status-badge ${isLive(execution) ? "live" : (execution.summary && execution.summary.completed ? "good" : "poor")}`;
  span.textContent = execution.status;
  return span;
}

async function loadFlights(missionId) {
  const { ok, data } = await api("GET", `/api/missions/${missionId}/executions`);
  const list = $("#flight-list");
  if (!ok || !state.mission || state.mission.id !== missionId) return;
  list.innerHTML = "";
  const flights = rowsOf(data, "executions");
  if (!flights.length) {
    const li = document.createElement("li");
    li.className = "muted";
    li.textContent = "not flown yet";
    list.appendChild(li);
    return;
  }
  for (const e of flights) {
    const li = document.createElement("li");
    li.dataset.id = e.id;
    li.dataset.status = e.status;
    li.classList.toggle("selected", e.id === state.execution);
    const when = new Date(e.created_at).toLocaleTimeString();
    li.append(flightBadge(e), ` ${e.id} · ${when}`);
    if (e.summary && e.summary.goal_error_max !== undefined) li.append(` · goal error ${fmt(e.summary.goal_error_max, 2)} m`);
    li.title = isLive(e) ? "flying: follow it" : "reopen: summary, events, replay";
    li.addEventListener("click", () => openFlight(e.id));
    list.appendChild(li);
  }
}

async function openFlight(id) {
  const { ok, data } = await api("GET", `/api/executions/${id}`);
  if (!ok) return;
  if (isLive(data)) { followExecution(data); return; }
  if (state.flightActive) return;  // the flight under way keeps the screen
  stopPlay();
  state.execution = id;
  clearFlightView();
  setExecutionStatus(data.status, Boolean(data.summary && data.summary.completed));
  showFlightSummary(data);
  $$("#flight-list li").forEach((li) => li.classList.toggle("selected", li.dataset.id === id));
  let events = data.events;
  let record = null;
  if (data.has_record !== false) {
    const r = await api("GET", `/api/executions/${id}/record`);
    if (r.ok) record = r.data;
  }
  if (!events && record) events = record.events;
  $("#event-log").innerHTML = "";
  for (const e of events || []) logEvent(e);
  if (record) startReplay(id, record);
}

// Replay: recorded positions against the plan, on mission time (record t - mission_start).
function startReplay(id, record) {
  const t0 = record.mission_start ?? 0;
  state.replay = {
    id,
    vehicles: record.vehicles.map((v) => ({
      id: v.id, t: v.telemetry.t.map((t) => t - t0), position: v.telemetry.position,
    })).filter((v) => v.t.length),
  };
  const scale = state.mission.plan.scenario.separation_scale || [1, 1, 1];
  state.measured = measuredSeparation(state.replay.vehicles, scale, horizon());
  if (state.measured) state.measured.label = `measured (flight ${id})`;
  if (state.sepTraj) renderSeparation(state.mission.plan, state.sepTraj);
  $("#follow").checked = false;
  const slider = $("#time-slider");
  slider.value = slider.max;  // the end: where everyone went; ▶ or the slider replays it
  setTime(Number(slider.value));
}

function closeReplay() {
  if (!state.replay) return;
  state.replay = null;
  state.measured = null;
  if (state.sepTraj && state.mission) renderSeparation(state.mission.plan, state.sepTraj);
}

// ------------------------------------------------------------------ missions list

async function refreshMissionList() {
  const [missions, flights] = await Promise.all([
    api("GET", "/api/missions?limit=30"), api("GET", "/api/executions"),
  ]);
  if (!missions.ok) return;
  // Flights per mission, newest first (the executions list is newest first).
  const byMission = new Map();
  for (const e of flights.ok ? rowsOf(flights.data, "executions") : []) {
    if (!byMission.has(e.mission_id)) byMission.set(e.mission_id, []);
    byMission.get(e.mission_id).push(e);
  }
  const list = $("#mission-list");
  list.innerHTML = "";
  for (const m of rowsOf(missions.data, "missions")) {
    const li = document.createElement("li");
    li.dataset.id = m.id;
    li.classList.toggle("selected", Boolean(state.mission && state.mission.id === m.id));
    const when = new Date(m.created_at).toLocaleString();
    const name = document.createElement("b");
    name.textContent = m.name;
    const plan = m.plan_status ? (m.plan_ok ? "verified" : `${m.plan_status}, not verified`) : m.status;
    li.append(name, ` · ${m.vehicle_count} vehicles · ${plan} · `);
    const flown = byMission.get(m.id) || (m.flights ? null : []);
    const count = flown ? flown.length : m.flights.count;
    const flightsSpan = document.createElement("span");
    flightsSpan.className = "flight-count";
    flightsSpan.textContent = count ? `${count} flight${count > 1 ? "s" : ""} ` : "not flown ";
    li.append(flightsSpan);
    if (flown && flown.length) li.append(flightBadge(flown[0]));
    const small = document.createElement("span");
    small.className = "muted small";
    small.textContent = ` ${when}`;
    li.append(small);
    li.addEventListener("click", async () => {
      const got = await api("GET", `/api/missions/${m.id}`);
      if (!got.ok) return;
      if (state.planStream) { state.planStream.close(); state.planStream = null; }
      fillForm(got.data.scenario);
      state.presetName = null;
      state.rejected = false;
      showMission(m.id, formKey());
    });
    list.appendChild(li);
  }
}

// ------------------------------------------------------------------ fleet and service status

async function refreshVehicles() {
  const { ok, data } = await api("GET", "/api/vehicles");
  if (!ok) return;
  state.vehicles = data.vehicles;
  const hadOrigin = Boolean(origin());
  state.fleet = { ...(state.fleet || {}), ...data.fleet };
  if (Boolean(origin()) !== hadOrigin) drawFlyStatic();
  showVehicleTable();
  updateFlyButton();
  if (data.fleet.flying && data.fleet.flying !== state.execution && !state.flightActive) {
    pollExecution(data.fleet.flying);  // a flight started elsewhere: show it (and its Abort)
  }
}

async function refreshStatus() {
  const { ok, data } = await api("GET", "/api/status");
  const el = $("#service-status");
  if (!ok) { el.textContent = "service unreachable"; el.className = "bad"; return; }
  el.className = "muted";
  state.statuses = data.statuses || state.statuses;
  const fleet = data.fleet;
  el.textContent = `${fleet.kind === "none" ? "no fleet" : `${fleet.vehicles} ${fleet.kind} vehicles`} · planning ${data.planning_jobs}`;
  el.title = `fleetplan ${data.version}: fleet ${fleet.kind}, ${data.planning_jobs} planning jobs`;
  state.fleet = { ...(state.fleet || {}), ...fleet };
  updateFlyButton();
}

// ------------------------------------------------------------------ start

async function start() {
  buildLimitRows();
  $("#scenario-form").addEventListener("submit", submitPlan);
  $("#scenario-form").addEventListener("input", formEdited);
  $("#sequence-plan").addEventListener("click", submitSequence);
  $("#sequence-file").addEventListener("change", loadSequenceFile);
  $("#sequence-json").addEventListener("input", refreshStale);
  $("#preset").addEventListener("change", presetChosen);
  $("#preset-load").addEventListener("click", () => loadPreset());
  $("#add-vehicle").addEventListener("click", () => {
    const { lo, hi } = workspace();
    const mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 1];
    addVehicleRow({ id: nextVehicleId(), start: mid.map(round2), goal: mid.map(round2) });
    selectVehicle(vehicleRows().length - 1);
    $('input[name="place"][value="start"]').checked = true;
    formEdited();
  });
  $("#top-view").addEventListener("click", onTopViewClick);
  $("#time-slider").addEventListener("input", (ev) => {
    $("#follow").checked = false;  // the operator looks elsewhere in time; "follow" brings it back
    setTime(Number(ev.target.value));
  });
  $("#follow").addEventListener("change", () => drawTelemetry(state.live));
  $("#play").addEventListener("click", togglePlay);
  $("#fly-button").addEventListener("click", fly);
  $("#pause-button").addEventListener("click", () => pauseOrResume("pause"));
  $("#resume-button").addEventListener("click", () => pauseOrResume("resume"));
  for (const b of $$(".fleet-commands button")) b.addEventListener("click", () => fleetCommand(b.dataset.command));
  $("#abort-button").addEventListener("click", abortAll);
  await refreshStatus();  // the status sets first: every mission shown is judged by them
  // The first preset fills the form, unless the operator started typing meanwhile.
  loadExampleList().then(() => { if (!state.touched) loadPreset(true); });
  loadCapabilities();
  refreshMissionList();
  refreshVehicles();
  setInterval(refreshStatus, 5000);
  setInterval(refreshVehicles, 2000);
}

document.addEventListener("DOMContentLoaded", start);
