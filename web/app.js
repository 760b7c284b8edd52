// fleetplan browser page: enter a fleet, plan it, inspect the plan, fly it, abort.
// Plain JavaScript, no build step; talks only to this service's /api (see /docs).
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);
const $$ = (sel, root = document) => Array.from(root.querySelectorAll(sel));
const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
const color = (i) => COLORS[i % COLORS.length];
const AXES = ["x", "y", "z"];
const LIMIT_KEYS = ["position_min", "position_max", "velocity_max", "acceleration_max", "jerk_max"];
const PLOT_CONFIG = { responsive: true, displaylogo: false };

const state = {
  mission: null,       // the mission document (GET /api/missions/{id})
  traj: null,          // /trajectory?rate=10 for the 3-D view and slider
  sep: null,           // {t, d} minimum pairwise separation over time
  selected: 0,         // vehicle row the top view places points for
  extra: {},           // scenario keys without inputs (separation_scale, ...), kept as loaded
  limitExtras: {},     // limits without inputs (thrust_min, thrust_max, body_rate_max)
  planStream: null,    // EventSource of the planning progress
  execution: null,     // id of the flight shown
  flightStream: null,  // EventSource of the flight telemetry
  playTimer: null,
};

// ------------------------------------------------------------------ HTTP

let tokenAsked = null;  // one token prompt shared by concurrent requests

async function api(method, url, body) {
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.body = JSON.stringify(body);
    init.headers["Content-Type"] = "application/json";
  }
  let response = await fetch(url, init);
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
  return { status: response.status, ok: response.ok, data };
}

// Append to a log list and keep the list (not the page) scrolled to its end.
function appendScrolled(list, item) {
  list.appendChild(item);
  list.scrollTop = list.scrollHeight;
}

const fmt = (x, digits = 3) => (x === null || x === undefined || Number.isNaN(x)) ? "–"
  : (typeof x === "number" ? Number(x.toFixed(digits)).toString() : String(x));

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
  tr.addEventListener("input", drawTopView);
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
  drawTopView();
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
    option.textContent = `${example.name} (${example.vehicles})`;
    group.appendChild(option);
  }
  $("#preset").value = "example:paper-circle4";
}

function transferSteps(distance, dt) {
  // Time for a rest-to-rest move at 2 m/s, 3 m/s², with slack for avoidance manoeuvres.
  const t = distance / 2 + 2 / 3;
  return Math.ceil((1.6 * t + 4) / dt);
}

function circleScenario(n) {
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

function randomScenario(n) {
  const R = 1.0;
  const side = Math.max(5, Math.ceil(Math.sqrt(n * 6)));
  const size = [side, side, 4];
  const pick = (taken) => {
    for (let tries = 0; tries < 10000; tries++) {
      const p = [0.5 + Math.random() * (side - 1), 0.5 + Math.random() * (side - 1),
                 1 + Math.random() * 2.5].map(round2);
      if (taken.every((q) => Math.hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]) >= 1.5 * R)) return p;
    }
    throw new Error("workspace too crowded");
  };
  const starts = [], goals = [];
  for (let i = 0; i < n; i++) { starts.push(pick(starts)); goals.push(pick(goals)); }
  const far = Math.max(...starts.map((s, i) => Math.hypot(...s.map((v, a) => v - goals[i][a]))));
  return {
    name: `random${n}`, dt: 0.2, steps: transferSteps(far, 0.2), min_separation: R,
    limits: standardLimits(size),
    vehicles: starts.map((s, i) => ({ id: `uav${i + 1}`, start: s, goal: goals[i] })),
  };
}

const round2 = (x) => Math.round(x * 100) / 100;
const standardLimits = (max) => ({
  position_min: [0, 0, 0], position_max: max.map(round2),
  velocity_max: [2, 2, 2], acceleration_max: [3, 3, 3], jerk_max: [5, 5, 5],
});

async function loadPreset() {
  const choice = $("#preset").value;
  const n = Math.max(2, Math.min(128, Number($("#preset-count").value) || 8));
  if (choice === "gen:circle") return fillForm(circleScenario(n));
  if (choice === "gen:random") return fillForm(randomScenario(n));
  const { ok, data } = await api("GET", `/api/examples/${choice.slice(8)}`);
  if (ok) fillForm(data);
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
  drawTopView();
}

// ------------------------------------------------------------------ errors next to fields

function clearErrors() {
  $$("input.invalid").forEach((i) => { i.classList.remove("invalid"); i.title = ""; });
  $$(".field-error").forEach((d) => { d.textContent = ""; });
  $$("tr.error-row").forEach((r) => r.remove());
}

function showError(field, reason) {
  const path = field || "";
  const matches = $$("#scenario-form input[data-field]").filter((input) => {
    const f = input.dataset.field;
    return path && (f === path || f.startsWith(`${path}[`) || f.startsWith(`${path}.`) ||
                    path.startsWith(`${f}[`));
  });
  for (const input of matches) { input.classList.add("invalid"); input.title = reason; }
  const vehicle = /^vehicles\[(\d+)\]/.exec(path);
  if (vehicle && vehicleRows()[Number(vehicle[1])]) {
    const tr = vehicleRows()[Number(vehicle[1])];
    const row = document.createElement("tr");
    row.className = "error-row";
    const td = document.createElement("td");
    td.colSpan = 8;
    td.className = "vehicle-error";
    td.textContent = `${path}: ${reason}`;
    row.appendChild(td);
    tr.after(row);
    return;
  }
  const head = path.split(/[.[]/)[0];
  const box = $$(".field-error[data-error-for]").find((d) => d.dataset.errorFor.split(" ").includes(head));
  (box || $("#form-error")).textContent = path ? `${path}: ${reason}` : reason;
}

// ------------------------------------------------------------------ planning

async function submitPlan(ev) {
  ev.preventDefault();
  clearErrors();
  if (state.planStream) state.planStream.close();
  const scenario = readScenario();
  $("#plan-button").disabled = true;
  $("#plan-state").textContent = "submitting…";
  $("#progress-log").innerHTML = "";
  const { status, data } = await api("POST", "/api/missions?wait=0", scenario);
  if (status !== 201 && status !== 202) {
    $("#plan-button").disabled = false;
    $("#plan-state").textContent = `rejected (${status})`;
    for (const e of (data && data.errors) || [{ field: data && data.field, reason: (data && data.reason) || "error" }]) {
      showError(e.field, e.reason);
    }
    return;
  }
  followPlanning(data);
}

function followPlanning(mission) {
  state.mission = mission;
  $("#mission-title").textContent = `${mission.name} · ${mission.id}`;
  if (mission.status !== "planning") { showMission(mission.id); return; }
  $("#plan-state").textContent = "planning…";
  const source = new EventSource(`/api/missions/${mission.id}/events`);
  state.planStream = source;
  source.addEventListener("iteration", (ev) => {
    const r = JSON.parse(ev.data);
    const li = document.createElement("li");
    li.textContent = `iteration ${r.iteration}: cost ${fmt(r.cost, 2)}` +
      (r.cost_change === null ? "" : ` (Δ ${fmt(r.cost_change, 3)})`) +
      `, ${r.separation_rows} separation rows, ${r.qp_solves} QP solves, ${fmt(r.seconds, 3)} s`;
    appendScrolled($("#progress-log"), li);
    $("#plan-state").textContent = `planning… iteration ${r.iteration}`;
  });
  source.addEventListener("done", () => { source.close(); showMission(mission.id); });
  source.onerror = () => {  // stream lost: fall back to polling the mission
    source.close();
    setTimeout(() => showMission(mission.id), 1000);
  };
}

async function showMission(id) {
  const { ok, data } = await api("GET", `/api/missions/${id}`);
  $("#plan-button").disabled = false;
  if (!ok) { $("#plan-state").textContent = data.reason; return; }
  state.mission = data;
  $("#mission-title").textContent = `${data.name} · ${data.id}`;
  refreshMissionList();
  if (data.status === "planning") { followPlanning(data); return; }
  if (data.status === "failed") {
    $("#plan-state").innerHTML = "";
    $("#plan-state").append(badge(false, `planning failed: ${data.error ? data.error.reason : ""}`));
    if (data.error && data.error.field) showError(data.error.field, data.error.reason);
    return;
  }
  $("#plan-state").innerHTML = "";
  $("#plan-state").append(badge(data.plan_ok, `${data.plan_status}${data.plan_ok ? ", verified" : ", not verified"}`));
  $("#plan-state").title = data.plan.message || "";
  if (!data.plan_ok && data.plan.message) $("#plan-state").append(` · ${data.plan.message}`);
  await renderPlan(data);
}

function badge(good, text) {
  const span = document.createElement("span");
  span.className = good ? "ok" : "bad";
  span.textContent = text;
  return span;
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
  renderSummary(plan);
  render3d(plan, traj.data);
  renderSeparation(plan, sepTraj.data);
  renderSpeed(sepTraj.data);
  renderThrust(plan);
  $("#fly-button").disabled = false;
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

function renderSummary(plan) {
  $("#summary").hidden = false;
  const v = plan.verification || {};
  const R = plan.scenario.min_separation;
  const ver = $("#verification");
  ver.innerHTML = "<caption>verification</caption>";
  row(ver, "status", `${plan.status}${plan.message ? ": " + plan.message : ""}`, plan.status === "converged");
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
    marker: { size: 5, color: traj.vehicles.map((_, i) => color(i)) },
  };
  const flown = {
    type: "scatter3d", mode: "markers", name: "flown (live)",
    x: [], y: [], z: [], text: [], hoverinfo: "text",
    marker: { size: 6, symbol: "diamond", color: "#000" },
  };
  const s = plan.scenario.limits;
  const layout = {
    margin: { l: 0, r: 0, t: 24, b: 0 }, showlegend: !many,
    title: { text: "trajectories (world frame, z up)", font: { size: 13 } },
    scene: {
      aspectmode: "data",
      xaxis: { title: { text: "x (m)" }, range: [s.position_min[0], s.position_max[0]] },
      yaxis: { title: { text: "y (m)" }, range: [s.position_min[1], s.position_max[1]] },
      zaxis: { title: { text: "z (m)" }, range: [s.position_min[2], s.position_max[2]] },
    },
    uirevision: "keep",
  };
  Plotly.react("plot3d", [...lines, now, flown], layout, PLOT_CONFIG);
  const slider = $("#time-slider");
  slider.max = traj.t.length - 1;
  slider.value = 0;
  $("#time-controls").hidden = false;
  setTime(0);
}

function setTime(k) {
  const traj = state.traj;
  if (!traj) return;
  const index = traj.vehicles.length;  // the "planned now" trace follows the lines
  const pos = traj.vehicles.map((v) => v.position[k]);
  Plotly.restyle("plot3d", { x: [pos.map((p) => p[0])], y: [pos.map((p) => p[1])], z: [pos.map((p) => p[2])] }, [index]);
  $("#time-label").textContent = `t = ${traj.t[k].toFixed(1)} s`;
}

function togglePlay() {
  if (state.playTimer) { clearInterval(state.playTimer); state.playTimer = null; $("#play").textContent = "▶"; return; }
  $("#play").textContent = "⏸";
  const slider = $("#time-slider");
  state.playTimer = setInterval(() => {
    let k = Number(slider.value) + 1;
    if (k > Number(slider.max)) k = 0;
    slider.value = k;
    setTime(k);
  }, 1000 / state.traj.rate);
}

function minSeparation(plan, traj) {
  const scale = plan.scenario.separation_scale || [1, 1, 1];
  const n = traj.vehicles.length;
  const d = traj.t.map((_, k) => {
    let best = Infinity;
    for (let i = 0; i < n; i++) {
      const p = traj.vehicles[i].position[k];
      for (let j = i + 1; j < n; j++) {
        const q = traj.vehicles[j].position[k];
        const dist = Math.hypot((p[0] - q[0]) / scale[0], (p[1] - q[1]) / scale[1], (p[2] - q[2]) / scale[2]);
        if (dist < best) best = dist;
      }
    }
    return best;
  });
  return { t: traj.t, d };
}

function renderSeparation(plan, traj) {
  const R = plan.scenario.min_separation;
  if (traj.vehicles.length < 2) { Plotly.purge("separation-plot"); return; }
  state.sep = minSeparation(plan, traj);
  const low = Math.min(...state.sep.d);
  Plotly.react("separation-plot", [
    { x: state.sep.t, y: state.sep.d, mode: "lines", name: "min pairwise distance", line: { color: "#1f6feb" } },
    { x: [0, traj.t[traj.t.length - 1]], y: [R, R], mode: "lines", name: `R = ${R} m`, line: { color: "#c62828", dash: "dash" } },
  ], {
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

// ------------------------------------------------------------------ missions list

async function refreshMissionList() {
  const { ok, data } = await api("GET", "/api/missions?limit=30");
  if (!ok) return;
  const list = $("#mission-list");
  list.innerHTML = "";
  for (const m of data.missions) {
    const li = document.createElement("li");
    li.dataset.id = m.id;
    const when = new Date(m.created_at).toLocaleString();
    li.textContent = `${m.name} · ${m.vehicle_count} vehicles · ${m.status}` +
      (m.plan_status ? ` (${m.plan_status})` : "") + ` · ${when}`;
    li.addEventListener("click", async () => {
      const got = await api("GET", `/api/missions/${m.id}`);
      if (got.ok) { fillForm(got.data.scenario); showMission(m.id); }
    });
    list.appendChild(li);
  }
}

// ------------------------------------------------------------------ flying

const ACTIVE = ["starting", "running", "aborting"];

async function fly() {
  if (!state.mission) return;
  $("#fly-button").disabled = true;
  $("#event-log").innerHTML = "";
  $("#flight-summary").textContent = "";
  const { status, data } = await api("POST", `/api/missions/${state.mission.id}/executions`);
  if (status !== 201) {
    $("#execution-status").textContent = `refused (${status}): ${data.reason}`;
    $("#execution-status").className = "bad";
    $("#fly-button").disabled = false;
    return;
  }
  followExecution(data);
}

function followExecution(execution) {
  if (state.flightStream) state.flightStream.close();
  state.execution = execution.id;
  setExecutionStatus(execution.status);
  const source = new EventSource(`/api/executions/${execution.id}/events`);
  state.flightStream = source;
  source.addEventListener("telemetry", (ev) => showTelemetry(JSON.parse(ev.data)));
  source.addEventListener("event", (ev) => logEvent(JSON.parse(ev.data)));
  source.addEventListener("status", (ev) => setExecutionStatus(JSON.parse(ev.data).status));
  source.addEventListener("done", (ev) => {
    source.close();
    state.flightStream = null;
    const done = JSON.parse(ev.data);
    setExecutionStatus(done.status);
    showFlightSummary(done);
    $("#fly-button").disabled = false;
  });
  source.onerror = () => {  // stream lost: poll the execution instead
    source.close();
    state.flightStream = null;
    setTimeout(() => pollExecution(execution.id), 1000);
  };
}

async function pollExecution(id) {
  const { ok, data } = await api("GET", `/api/executions/${id}`);
  if (!ok) return;
  setExecutionStatus(data.status);
  if (ACTIVE.includes(data.status)) followExecution(data);
  else { showFlightSummary(data); $("#fly-button").disabled = false; }
}

function setExecutionStatus(status) {
  const el = $("#execution-status");
  el.textContent = `flight ${state.execution}: ${status}`;
  el.dataset.status = status;
  el.className = status === "completed" ? "ok" : (ACTIVE.includes(status) ? "" : "bad");
  $("#flight-banner").textContent = ACTIVE.includes(status) ? `✈ flight ${state.execution}: ${status}` : "";
}

function showVehicleTable(vehicles) {
  const tbody = $("#vehicle-state tbody");
  tbody.innerHTML = "";
  for (const v of vehicles) {
    const tr = document.createElement("tr");
    tr.dataset.id = v.id;
    const age = v.heartbeat_age === null || v.heartbeat_age === undefined ? "–" : `${v.heartbeat_age.toFixed(1)} s`;
    const pos = v.position ? v.position.map((x) => x.toFixed(2)).join(", ") : "–";
    const err = v.tracking_error === null || v.tracking_error === undefined ? "" : ` (±${v.tracking_error.toFixed(2)} m)`;
    const armed = v.armed === null || v.armed === undefined ? "–" : (v.armed ? "armed" : "disarmed");
    for (const text of [v.id, v.phase ?? "idle", v.mode ?? "–", armed, age, pos + err]) {
      const td = document.createElement("td");
      td.textContent = text;
      tr.appendChild(td);
    }
    if (v.fault) tr.className = "bad";
    tbody.appendChild(tr);
  }
}

function showTelemetry(t) {
  showVehicleTable(t.vehicles);
  const clock = t.mission_time === null ? "" : ` · t = ${t.mission_time.toFixed(1)} / ${t.horizon.toFixed(0)} s`;
  const sep = t.min_separation_live === null ? "" : ` · closest pair now ${t.min_separation_live.toFixed(2)} m`;
  $("#flight-phase").textContent = `${t.phase}${clock}${sep}`;
  const xs = [], ys = [], zs = [], ids = [];
  for (const v of t.vehicles) {
    if (v.position) { xs.push(v.position[0]); ys.push(v.position[1]); zs.push(v.position[2]); ids.push(v.id); }
  }
  if (state.traj && $("#plot3d").data) {
    Plotly.restyle("plot3d", { x: [xs], y: [ys], z: [zs], text: [ids] }, [state.traj.vehicles.length + 1]);
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
  const ids = new Set(ok ? data.executions.map((e) => e.id) : []);
  if (state.execution && ACTIVE.includes($("#execution-status").dataset.status)) ids.add(state.execution);
  if (!ids.size) { $("#flight-banner").textContent = "nothing is flying"; return; }
  for (const id of ids) {
    const r = await api("POST", `/api/executions/${id}/abort`, { action: "land" });
    if (r.ok && id === state.execution) setExecutionStatus(r.data.status);
  }
}

async function refreshVehicles() {
  if (state.flightStream) return;  // the flight's telemetry fills the table meanwhile
  const { ok, data } = await api("GET", "/api/vehicles");
  if (!ok) return;
  showVehicleTable(data.vehicles);
  if (data.fleet.flying && data.fleet.flying !== state.execution) {
    pollExecution(data.fleet.flying);  // a flight started elsewhere: show it (and its Abort)
  }
}

// ------------------------------------------------------------------ service status

async function refreshStatus() {
  const { ok, data } = await api("GET", "/api/status");
  const el = $("#service-status");
  if (!ok) { el.textContent = "service unreachable"; el.className = "bad"; return; }
  el.className = "muted";
  const fleet = data.fleet;
  el.textContent = `fleet: ${fleet.kind === "none" ? "none" : `${fleet.vehicles} ${fleet.kind} vehicles`} · planning jobs: ${data.planning_jobs}`;
  $("#fleet-label").textContent = fleet.kind === "none" ? "no fleet configured" : `on ${fleet.vehicles} ${fleet.kind} vehicles`;
}

// ------------------------------------------------------------------ start

function start() {
  buildLimitRows();
  $("#scenario-form").addEventListener("submit", submitPlan);
  $("#preset-load").addEventListener("click", loadPreset);
  $("#add-vehicle").addEventListener("click", () => {
    const { lo, hi } = workspace();
    const mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 1];
    addVehicleRow({ id: nextVehicleId(), start: mid.map(round2), goal: mid.map(round2) });
    selectVehicle(vehicleRows().length - 1);
    $('input[name="place"][value="start"]').checked = true;
  });
  $("#top-view").addEventListener("click", onTopViewClick);
  $$('tr[data-limit] input').forEach((i) => i.addEventListener("input", drawTopView));
  $("#time-slider").addEventListener("input", (ev) => setTime(Number(ev.target.value)));
  $("#play").addEventListener("click", togglePlay);
  $("#fly-button").addEventListener("click", fly);
  $("#abort-button").addEventListener("click", abortAll);
  loadExampleList().then(loadPreset);
  refreshMissionList();
  refreshStatus();
  refreshVehicles();
  setInterval(refreshStatus, 5000);
  setInterval(refreshVehicles, 2000);
}

document.addEventListener("DOMContentLoaded", start);
