// @ts-check
// Errors next to the fields they name: "vehicles[2].goal" marks that vehicle's three goal
// inputs and gets a line under its row; "obstacles[1]..." (or a reason naming obstacle 'id')
// marks that obstacle's row and drawing; an edit clears the errors about the field edited.
import { $, $$ } from "./dom.js";
import { obstacleRows, vehicleRows } from "./form.js";
import { drawTopView } from "./topview.js";

/** Remove every error shown. */
export function clearErrors() {
  $$("input.invalid").forEach((i) => { i.classList.remove("invalid"); i.title = ""; });
  $$(".field-error").forEach((d) => { d.textContent = ""; });
  $$("tr.error-row").forEach((r) => r.remove());
  markObstacles();
}

/** Obstacle rows some error shown names get `has-error` (drawn red on the top view). */
function markObstacles() {
  const named = new Set($$(".error-item[data-obstacle]").map((d) => Number(d.dataset.obstacle)));
  obstacleRows().forEach((tr, i) => tr.classList.toggle("has-error", named.has(i)));
  drawTopView();
}

/** The obstacle row an error is about: its path's index, else the obstacle its reason names
 * ("... inside obstacle 'pillar' ..."); -1 for none.
 * @param {string} path @param {string} reason @returns {number} */
function obstacleOf(path, reason) {
  const byPath = /^obstacles\[(\d+)\]/.exec(path);
  if (byPath) return Number(byPath[1]);
  const byName = /obstacle '([^']*)'/.exec(reason);
  if (!byName) return -1;
  return obstacleRows().findIndex((tr) => /** @type {HTMLInputElement} */ ($("input", tr)).value === byName[1]);
}

/** A line under a table row (a vehicle's or an obstacle's) holding its errors.
 * @param {HTMLTableRowElement} tr @param {number} span @returns {HTMLElement} */
function errorCell(tr, span) {
  let row = /** @type {HTMLElement | null} */ (tr.nextElementSibling);
  if (!row || !row.classList.contains("error-row")) {
    row = document.createElement("tr");
    row.className = "error-row";
    const td = document.createElement("td");
    td.colSpan = span;
    td.className = "vehicle-error";
    row.appendChild(td);
    tr.after(row);
  }
  return /** @type {HTMLElement} */ (row.firstChild);
}

/** The inputs an error path names.
 * @param {string} path
 * @returns {HTMLInputElement[]} */
function inputsFor(path) {
  return $$("#scenario-form input[data-field]").filter((input) => {
    const f = input.dataset.field;
    return path && (f === path || f.startsWith(`${path}[`) || f.startsWith(`${path}.`) ||
                    path.startsWith(`${f}[`));
  });
}

/** The operator edited `input`: the errors about that field no longer hold.
 * @param {HTMLInputElement} input */
export function clearErrorsFor(input) {
  const field = input.dataset && input.dataset.field;
  if (!field) return;
  // An obstacle edited: the errors naming it (a vehicle inside it, say) no longer hold.
  const ob = /^obstacles\[(\d+)\]/.exec(field);
  for (const item of $$(".error-item")) {
    if (inputsFor(item.dataset.path).includes(input) || (ob && item.dataset.obstacle === ob[1])) {
      for (const marked of inputsFor(item.dataset.path)) { marked.classList.remove("invalid"); marked.title = ""; }
      const row = item.closest("tr.error-row");
      item.remove();
      if (row && !$(".error-item", row)) row.remove();
    }
  }
  if (field.startsWith("obstacles[") || $(".error-item[data-obstacle]")) markObstacles();
  input.classList.remove("invalid");
  input.title = "";
  $("#form-error").textContent = "";
}

/** One error line, "path: reason".
 * @param {string} path
 * @param {string} reason
 * @returns {HTMLDivElement} */
export function errorItem(path, reason) {
  const div = document.createElement("div");
  div.className = "error-item";
  div.dataset.path = path;
  div.textContent = path ? `${path}: ${reason}` : reason;
  return div;
}

/** Show an error of the service's next to the field it names.
 * @param {string | undefined} field
 * @param {string} reason */
export function showError(field, reason) {
  const path = field || "";
  for (const input of inputsFor(path)) { input.classList.add("invalid"); input.title = reason; }
  const item = errorItem(path, reason);
  const ob = obstacleOf(path, reason);
  if (ob >= 0 && obstacleRows()[ob]) item.dataset.obstacle = String(ob);
  const vehicle = /^vehicles\[(\d+)\]/.exec(path);
  const tr = vehicle ? vehicleRows()[Number(vehicle[1])]
    : path.startsWith("obstacles[") && ob >= 0 ? obstacleRows()[ob] : undefined;
  if (tr) errorCell(tr, vehicle ? 8 : 4).appendChild(item);
  else {
    const head = path.split(/[.[]/)[0];
    const box = $$(".field-error[data-error-for]").find((d) => d.dataset.errorFor.split(" ").includes(head));
    (box || $("#form-error")).appendChild(item);
  }
  if (item.dataset.obstacle) markObstacles();
}

/** Whether any error is shown now.
 * @returns {boolean} */
export const hasErrors = () => Boolean($(".error-item"));
