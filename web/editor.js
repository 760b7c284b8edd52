// @ts-check
// The editor: vehicles added, removed, selected and placed on the top view; obstacles added,
// selected, moved and resized by dragging, and removed; every edit
// clears the errors it answers and marks the plan shown stale; presets fill the form.
import { api } from "./api.js";
import { $ } from "./dom.js";
import { clearErrors, clearErrorsFor, hasErrors } from "./fielderrors.js";
import { refreshStale } from "./flygate.js";
import { addObstacleRow, addVehicleRow, obstacleRows, renumberVehicles, vehicleRows, workspace,
         writeScenario } from "./form.js";
import { grabHandle, grabMove, polygonAt, valueAt } from "./grab.js";
import { circleScenario, randomScenario, round2 } from "./presets.js";
import { editor, planning, service } from "./state.js";
import { drawTopView, worldAt } from "./topview.js";

/** @typedef {import("./state.js").Scenario} Scenario */

const obstacleEvents = { onRemove: removeObstacle, onSelect: selectObstacle };
const rowEvents = { onRemove: removeVehicle, onSelect: selectVehicle, obstacle: obstacleEvents };

/** @param {HTMLTableRowElement} tr */
function removeObstacle(tr) {
  const next = tr.nextElementSibling;
  if (next && next.classList.contains("error-row")) next.remove();
  tr.remove();
  renumberVehicles();
  editor.obstacle = -1;
  formEdited();
}

/** The obstacle drawn bold, its row highlighted.
 * @param {number} index */
function selectObstacle(index) {
  editor.obstacle = index;
  obstacleRows().forEach((tr, i) => tr.classList.toggle("selected", i === index));
  drawTopView();
}

/** "Add box" / "Add cylinder": a new obstacle (1 m across, the workspace's height) in the
 * middle of the workspace, selected.
 * @param {"box" | "cylinder"} kind */
export function addObstacle(kind) {
  const { lo, hi } = workspace();
  const [mx, my] = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2].map(round2);
  const top = round2(hi[2] ?? 3);
  const ids = new Set(obstacleRows().map((tr) => /** @type {HTMLInputElement} */ ($("input", tr)).value));
  let n = obstacleRows().length + 1;
  while (ids.has(`${kind}${n}`)) n++;
  addObstacleRow(kind === "box"
    ? { id: `${kind}${n}`, box: { min: [mx - 0.5, my - 0.5, 0], max: [mx + 0.5, my + 0.5, top] } }
    : { id: `${kind}${n}`, cylinder: { center: [mx, my], radius: 0.5, z: [0, top] } }, obstacleEvents);
  selectObstacle(obstacleRows().length - 1);
  formEdited();
}

/** A drag of an obstacle on the top view, moving it or resizing it by a handle: where it
 * began, the fields it drives (grab.js) and a prism's polygon when one moves. */
const drag = {
  active: false, moved: false, suppressClick: false, start: [0, 0],
  fields: /** @type {import("./grab.js").Grabbed[]} */ ([]),
  polygon: /** @type {import("./grab.js").GrabbedPolygon | null} */ (null),
};

/** Pointer down on an obstacle drawing: select it and start moving it, or, on one of the
 * selected obstacle's handles, resizing it.
 * @param {PointerEvent} ev */
export function onTopViewPointerDown(ev) {
  const target = /** @type {Element} */ (ev.target);
  const g = target.closest("g.obstacle");
  if (!g) return;
  const index = Number(g.getAttribute("data-index"));
  const tr = obstacleRows()[index];
  if (!tr) return;
  ev.preventDefault();
  const handle = target.closest("g.handle")?.getAttribute("data-handle");
  selectObstacle(index);
  drag.start = worldAt(ev);
  const grab = handle ? { fields: grabHandle(tr, handle, workspace()), polygon: null } : grabMove(tr);
  drag.fields = grab.fields;
  drag.polygon = grab.polygon;
  drag.active = true;
  drag.moved = false;
  $("#top-view").setPointerCapture?.(ev.pointerId);
}

/** Pointer moves while dragging: the fields grabbed follow the pointer, within their bounds;
 * the table row and the drawing (solid, clearance, handles) with them.
 * @param {PointerEvent} ev */
export function onTopViewPointerMove(ev) {
  if (!drag.active) return;
  const at = worldAt(ev);
  for (const f of drag.fields) f.input.value = String(valueAt(f, drag.start, at));
  if (drag.polygon) drag.polygon.tr.dataset.polygon = JSON.stringify(polygonAt(drag.polygon, drag.start, at));
  drag.moved = true;
  // A prism has no x, y fields: its first field (a height) names the obstacle edited.
  const edited = drag.polygon ? [$("input[data-path]", drag.polygon.tr)] : drag.fields.map((f) => f.input);
  for (const input of edited) if (input) clearErrorsFor(input);
  formEdited();
}

/** Pointer up (or cancelled): the drag ends (the click that follows places no vehicle point). */
export function onTopViewPointerUp() {
  if (!drag.active) return;
  drag.active = false;
  drag.suppressClick = true;
}

/** @param {HTMLTableRowElement} tr */
function removeVehicle(tr) {
  const next = tr.nextElementSibling;
  if (next && next.classList.contains("error-row")) next.remove();
  tr.remove();
  renumberVehicles();
  editor.selected = Math.min(editor.selected, vehicleRows().length - 1);
  formEdited();
}

/** The row the top view places points for.
 * @param {number} index */
function selectVehicle(index) {
  editor.selected = index;
  vehicleRows().forEach((tr, i) => tr.classList.toggle("selected", i === index));
  drawTopView();
}

function nextVehicleId() {
  const ids = new Set(vehicleRows().map((tr) => /** @type {HTMLInputElement} */ ($("input", tr)).value));
  let n = vehicleRows().length + 1;
  while (ids.has(`uav${n}`)) n++;
  return `uav${n}`;
}

/** "Add vehicle": a new row in the middle of the workspace, selected, its start placed next. */
export function addVehicle() {
  const { lo, hi } = workspace();
  const mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 1];
  addVehicleRow({ id: nextVehicleId(), start: mid.map(round2), goal: mid.map(round2) }, rowEvents);
  selectVehicle(vehicleRows().length - 1);
  $('input[name="place"][value="start"]').checked = true;
  formEdited();
}

/** A click on the top view places the selected vehicle's start, then its goal.
 * @param {MouseEvent} ev */
export function onTopViewClick(ev) {
  if (drag.suppressClick) { drag.suppressClick = false; return; }
  const [x, y] = worldAt(ev).map(round2);
  if (vehicleRows().length === 0) {
    addVehicleRow({ id: nextVehicleId(), start: [x, y, 1], goal: [x, y, 1] }, rowEvents);
    selectVehicle(0);
  }
  const which = $('input[name="place"]:checked').value;
  const tr = vehicleRows()[editor.selected];
  const inputs = Array.from(tr.querySelectorAll("input")).slice(1);
  const offset = which === "start" ? 0 : 3;
  inputs[offset].value = String(x);
  inputs[offset + 1].value = String(y);
  if (inputs[offset + 2].value === "") inputs[offset + 2].value = "1";
  // Start placed: the next click places this vehicle's goal.
  $(`input[name="place"][value="${which === "start" ? "goal" : "start"}"]`).checked = true;
  formEdited();
}

/** Any change to the form (typed, clicked on the map, a row added or removed).
 * @param {Event} [ev] */
export function formEdited(ev) {
  const target = /** @type {any} */ (ev && ev.target);
  editor.touched = true;
  if (target && target.dataset) clearErrorsFor(target);
  // A preset edited is a new mission: say so in its name, unless the operator named it.
  const name = $("#f-name");
  if (target !== name && editor.presetName && name.value === editor.presetName) {
    name.value = `${editor.presetName}-edited`;
    editor.presetName = null;
  }
  if (target === name) editor.presetName = null;
  // "rejected (422)" described the form as it was: once edited, say what to do next.
  if (planning.rejected && !planning.planning && target) {
    $("#plan-state").textContent = hasErrors() ? "fix the fields marked, then Plan" : "edited: press Plan";
  }
  drawTopView();
  refreshStale();
}

/** Write a scenario into the form, its first vehicle selected, no errors left.
 * @param {Scenario} scenario */
export function fillForm(scenario) {
  writeScenario(scenario, rowEvents);
  clearErrors();
  editor.obstacle = -1;
  selectVehicle(0);
}

/** The paper cases the service bundles, in the preset menu. */
export async function loadExampleList() {
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

/** Why the generator cannot make `n` vehicles here ("" when it can): never fewer quietly.
 * @param {number} n */
function presetCountError(n) {
  const most = service.limits ? service.limits.max_vehicles : Infinity;
  if (n < 2) return `vehicles to generate: at least 2, got ${n}`;
  if (n > most) {
    return `vehicles to generate: ${n} exceed this server's limit of ${most} (setting ` +
      `max_vehicles: start the service with FLEETPLAN_MAX_VEHICLES=${n} to plan them)`;
  }
  return "";
}

/** The vehicle count applies to the generated presets only: shown with them alone. */
export function presetChosen() {
  $("#preset-count-label").hidden = !$("#preset").value.startsWith("gen:");
}

/** Fill the form with the preset chosen. `auto`: the page's first preset, which must not
 * land on a form the operator has touched.
 * @param {boolean} [auto] */
export async function loadPreset(auto = false) {
  if (auto && editor.touched) return;
  const choice = $("#preset").value;
  const n = Math.round(Number($("#preset-count").value) || 8);
  const tooMany = presetCountError(n);
  $("#preset-error").textContent = choice.startsWith("gen:") ? tooMany : "";
  if (choice.startsWith("gen:") && tooMany) return;
  let scenario = null;
  if (choice === "gen:circle") scenario = circleScenario(n);
  else if (choice === "gen:random") scenario = randomScenario(n);
  else if (choice.startsWith("example:")) {
    const { ok, data } = await api("GET", `/api/examples/${choice.slice(8)}`);
    if (!ok) return;
    scenario = data;
    if (auto && editor.touched) return;
  } else return;
  fillForm(scenario);
  editor.presetName = $("#f-name").value;
  refreshStale();
}
