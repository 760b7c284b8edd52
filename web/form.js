// @ts-check
// The scenario form: its inputs built and read as a scenario, a scenario written into it,
// and the form as one comparable key. No requests; edits are handled in editor.js.
import { $, $$ } from "./dom.js";
import { editor } from "./state.js";

/** @typedef {import("./state.js").Scenario} Scenario */
/** @typedef {import("./state.js").ScenarioVehicle} ScenarioVehicle */

export const LIMIT_KEYS = ["position_min", "position_max", "velocity_max", "acceleration_max", "jerk_max"];

/** @param {string} field @param {unknown} [value] @returns {HTMLInputElement} */
function numberInput(field, value) {
  const input = document.createElement("input");
  input.type = "number";
  input.step = "any";
  input.dataset.field = field;
  if (value !== undefined && value !== null) input.value = String(value);
  return input;
}

/** The x, y, z inputs of every limit row. */
export function buildLimitRows() {
  for (const key of LIMIT_KEYS) {
    const row = $(`tr[data-limit="${key}"]`);
    for (let a = 0; a < 3; a++) {
      const td = document.createElement("td");
      td.appendChild(numberInput(`limits.${key}[${a}]`));
      row.appendChild(td);
    }
  }
}

/** A table cell with a row's id input.
 * @param {string} field @param {string} id @returns {HTMLTableCellElement} */
function idCell(field, id) {
  const cell = document.createElement("td");
  const input = document.createElement("input");
  input.dataset.field = field;
  input.value = id;
  input.size = 6;
  cell.appendChild(input);
  return cell;
}

/** A table cell with a "✕" button removing its row (the click does not select the row).
 * @param {string} what "vehicle" or "obstacle" @param {() => void} onRemove
 * @returns {HTMLTableCellElement} */
function removeCell(what, onRemove) {
  const rm = document.createElement("td");
  const button = document.createElement("button");
  button.type = "button";
  button.textContent = "✕";
  button.title = `remove this ${what}`;
  button.className = `remove-${what}`;
  button.addEventListener("click", (ev) => { ev.stopPropagation(); onRemove(); });
  rm.appendChild(button);
  return rm;
}

/** @returns {HTMLTableRowElement[]} */
export function vehicleRows() { return $$("#vehicle-table tbody tr.vehicle"); }

/** A row of the vehicle table; `onRemove` and `onSelect` are the editor's.
 * @param {ScenarioVehicle} vehicle
 * @param {{onRemove: (tr: HTMLTableRowElement) => void, onSelect: (index: number) => void}} on */
export function addVehicleRow(vehicle, on) {
  const tbody = $("#vehicle-table tbody");
  const index = vehicleRows().length;
  const tr = document.createElement("tr");
  tr.className = "vehicle";
  tr.appendChild(idCell(`vehicles[${index}].id`, vehicle.id));
  for (const which of /** @type {const} */ (["start", "goal"])) {
    for (let a = 0; a < 3; a++) {
      const td = document.createElement("td");
      td.appendChild(numberInput(`vehicles[${index}].${which}[${a}]`, vehicle[which][a]));
      tr.appendChild(td);
    }
  }
  tr.appendChild(removeCell("vehicle", () => on.onRemove(tr)));
  tr.addEventListener("click", () => on.onSelect(vehicleRows().indexOf(tr)));
  tbody.appendChild(tr);
}

/** @returns {HTMLTableRowElement[]} */
export function obstacleRows() { return $$("#obstacle-table tbody tr.obstacle"); }

/** The numeric fields of each obstacle kind: [label, field path after the kind].
 * @type {Record<string, [string, string][]>} */
const OBSTACLE_FIELDS = {
  box: [["min x", "min[0]"], ["y", "min[1]"], ["z", "min[2]"], ["max x", "max[0]"], ["y", "max[1]"], ["z", "max[2]"]],
  cylinder: [["centre x", "center[0]"], ["y", "center[1]"], ["radius", "radius"], ["z from", "z[0]"], ["to", "z[1]"]],
  prism: [["z from", "z[0]"], ["to", "z[1]"]],
};

/** @param {any} obj @param {string} path "min[0]" or "radius" */
const fieldValue = (obj, path) => {
  const m = /^(\w+)(?:\[(\d)\])?$/.exec(path);
  if (!m || !obj) return undefined;
  return m[2] === undefined ? obj[m[1]] : (obj[m[1]] || [])[Number(m[2])];
};

/** A row of the obstacle table: id, kind and that kind's numeric fields (a prism's polygon
 * is kept as loaded, its heights editable); `on` is the editor's.
 * @param {import("./obstacles.js").Obstacle} ob
 * @param {{onRemove: (tr: HTMLTableRowElement) => void, onSelect: (index: number) => void}} on */
export function addObstacleRow(ob, on) {
  const kind = ob.box ? "box" : ob.cylinder ? "cylinder" : "prism";
  const shape = /** @type {any} */ (ob)[kind];
  const index = obstacleRows().length;
  const tr = document.createElement("tr");
  tr.className = "obstacle";
  tr.dataset.kind = kind;
  if (kind === "prism") tr.dataset.polygon = JSON.stringify(shape.polygon);
  const kindCell = document.createElement("td");
  kindCell.textContent = kind;
  const geo = document.createElement("td");
  geo.className = "obstacle-geometry";
  for (const [label, path] of OBSTACLE_FIELDS[kind]) {
    const l = document.createElement("label");
    l.textContent = `${label} `;
    const input = numberInput(`obstacles[${index}].${kind}.${path}`, fieldValue(shape, path));
    input.dataset.path = path;
    l.appendChild(input);
    geo.appendChild(l);
  }
  tr.append(idCell(`obstacles[${index}].id`, ob.id), kindCell, geo, removeCell("obstacle", () => on.onRemove(tr)));
  tr.addEventListener("click", () => on.onSelect(obstacleRows().indexOf(tr)));
  $("#obstacle-table tbody").appendChild(tr);
}

/** The obstacles the table says, in the contract's shape (null: a field left empty).
 * @returns {import("./obstacles.js").Obstacle[]} */
export function readObstacles() {
  return obstacleRows().map((tr) => {
    const kind = /** @type {string} */ (tr.dataset.kind);
    /** @type {Record<string, any>} */
    const shape = kind === "prism" ? { polygon: JSON.parse(tr.dataset.polygon || "[]") } : {};
    for (const input of $$("input[data-path]", tr)) {
      const m = /** @type {RegExpExecArray} */ (/^(\w+)(?:\[(\d)\])?$/.exec(/** @type {string} */ (input.dataset.path)));
      if (m[2] === undefined) shape[m[1]] = readNumber(input);
      else (shape[m[1]] ??= [])[Number(m[2])] = readNumber(input);
    }
    return { id: /** @type {HTMLInputElement} */ ($("input", tr)).value, [kind]: shape };
  });
}

/** Field names follow the rows' order after one is removed. */
export function renumberVehicles() {
  vehicleRows().forEach((tr, i) => {
    for (const input of $$("input", tr)) {
      input.dataset.field = input.dataset.field.replace(/^vehicles\[\d+\]/, `vehicles[${i}]`);
    }
  });
  obstacleRows().forEach((tr, i) => {
    for (const input of $$("input", tr)) {
      input.dataset.field = input.dataset.field.replace(/^obstacles\[\d+\]/, `obstacles[${i}]`);
    }
  });
}

/** @param {HTMLInputElement} input @returns {number | null} */
export const readNumber = (input) => (input.value.trim() === "" ? null : Number(input.value));

/** `steps`: a whole number, or "auto" (the planner chooses the horizon); any other text goes
 * to the service as typed, which names the field and what it takes.
 * @returns {number | string} */
function readSteps() {
  const text = $("#f-steps").value.trim();
  return text !== "" && text !== "auto" && Number.isFinite(Number(text)) ? Number(text) : text;
}

/** The scenario the form says, with the keys it has no inputs for.
 * @returns {Scenario} */
export function readScenario() {
  /** @param {string} name */
  const value = (name) => $(`#f-${name}`).value;
  /** @type {Record<string, any>} */
  const limits = {};
  for (const key of LIMIT_KEYS) {
    const v = $$(`tr[data-limit="${key}"] input`).map(readNumber);
    if (v.every((x) => x === null)) continue;  // optional bounds may be left empty
    limits[key] = v;
  }
  const vehicles = vehicleRows().map((tr) => {
    const inputs = $$("input", tr);
    const nums = inputs.slice(1).map(readNumber);
    return { id: inputs[0].value, start: nums.slice(0, 3), goal: nums.slice(3, 6) };
  });
  /** @type {Scenario} */
  const scenario = {
    name: value("name"),
    dt: /** @type {number} */ (readNumber($("#f-dt"))),
    steps: readSteps(),
    min_separation: /** @type {number} */ (readNumber($("#f-min_separation"))),
    method: /** @type {HTMLSelectElement} */ ($("#f-method")).value,
    limits,
    vehicles,
  };
  const obstacles = readObstacles();
  if (obstacles.length) scenario.obstacles = obstacles;
  const clearance = readNumber($("#f-obstacle_clearance"));
  if (clearance !== null) scenario.obstacle_clearance = clearance;
  Object.assign(scenario, editor.extra);
  Object.assign(scenario.limits, editor.limitExtras);
  return scenario;
}

/** Write a scenario into the form (the vehicle rows through `on`).
 * @param {Scenario} scenario
 * @param {{onRemove: (tr: HTMLTableRowElement) => void, onSelect: (index: number) => void,
 *   obstacle: {onRemove: (tr: HTMLTableRowElement) => void, onSelect: (index: number) => void}}} on */
export function writeScenario(scenario, on) {
  $("#f-name").value = scenario.name ?? "scenario";
  $("#f-dt").value = scenario.dt;
  $("#f-steps").value = String(scenario.steps);
  $("#f-min_separation").value = scenario.min_separation;
  /** @type {HTMLSelectElement} */ ($("#f-method")).value = scenario.method ?? "auto";
  for (const key of LIMIT_KEYS) {
    const v = scenario.limits[key];
    $$(`tr[data-limit="${key}"] input`).forEach((input, a) => { input.value = v ? v[a] : ""; });
  }
  // Keys the form has no inputs for travel along unchanged.
  editor.extra = {};
  for (const key of ["separation_scale", "cost_threshold", "max_iterations", "max_horizon"]) {
    if (scenario[key] !== undefined) editor.extra[key] = scenario[key];
  }
  editor.limitExtras = {};
  for (const key of ["thrust_min", "thrust_max", "body_rate_max"]) {
    if (scenario.limits[key] !== undefined) editor.limitExtras[key] = scenario.limits[key];
  }
  $("#vehicle-table tbody").innerHTML = "";
  for (const vehicle of scenario.vehicles) addVehicleRow(vehicle, on);
  $("#f-obstacle_clearance").value = scenario.obstacle_clearance ?? "";
  $("#obstacle-table tbody").innerHTML = "";
  for (const ob of scenario.obstacles ?? []) addObstacleRow(ob, on.obstacle);
}

/** The clearance kept from obstacles (m): the form's, else the planner's default R / 2.
 * @returns {number} */
export function obstacleClearance() {
  const c = readNumber($("#f-obstacle_clearance"));
  if (c !== null && Number.isFinite(c)) return c;
  const r = readNumber($("#f-min_separation"));
  return r !== null && Number.isFinite(r) ? r / 2 : 0;
}

/** The workspace box the form's position limits give (a default box while they are unset).
 * @returns {{lo: number[], hi: number[]}} */
export function workspace() {
  /** @param {string} key @returns {any[]} */
  const read = (key) => $$(`tr[data-limit="${key}"] input`).map(readNumber);
  const lo = read("position_min"), hi = read("position_max");
  const okBox = [0, 1].every((a) => Number.isFinite(lo[a]) && Number.isFinite(hi[a]) && hi[a] > lo[a]);
  return okBox ? { lo, hi } : { lo: [0, 0, 0], hi: [10, 10, 3] };
}

/** The form as one string: equal strings, same mission.
 * @returns {string} */
export const formKey = () => JSON.stringify(readScenario());

/** The sequence input as a key ("seq:" + its text): a mission planned from it is stale once
 * the text changes, whatever the form says.
 * @returns {string} */
export const sequenceKey = () => `seq:${$("#sequence-json").value}`;

/** The key of what is on screen now, of the kind `shown` is (form or sequence).
 * @param {string | null} shown
 * @returns {string} */
export const currentKey = (shown) => (shown && shown.startsWith("seq:") ? sequenceKey() : formKey());
