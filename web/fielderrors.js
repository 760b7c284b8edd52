// @ts-check
// Errors next to the fields they name: "vehicles[2].goal" marks that vehicle's three goal
// inputs and gets a line under its row; an edit clears the errors about the field edited.
import { $, $$ } from "./dom.js";
import { vehicleRows } from "./form.js";

/** Remove every error shown. */
export function clearErrors() {
  $$("input.invalid").forEach((i) => { i.classList.remove("invalid"); i.title = ""; });
  $$(".field-error").forEach((d) => { d.textContent = ""; });
  $$("tr.error-row").forEach((r) => r.remove());
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
  const vehicle = /^vehicles\[(\d+)\]/.exec(path);
  if (vehicle && vehicleRows()[Number(vehicle[1])]) {
    const tr = vehicleRows()[Number(vehicle[1])];
    let row = /** @type {HTMLElement | null} */ (tr.nextElementSibling);
    if (!row || !row.classList.contains("error-row")) {
      row = document.createElement("tr");
      row.className = "error-row";
      const td = document.createElement("td");
      td.colSpan = 8;
      td.className = "vehicle-error";
      row.appendChild(td);
      tr.after(row);
    }
    /** @type {HTMLElement} */ (row.firstChild).appendChild(errorItem(path, reason));
    return;
  }
  const head = path.split(/[.[]/)[0];
  const box = $$(".field-error[data-error-for]").find((d) => d.dataset.errorFor.split(" ").includes(head));
  (box || $("#form-error")).appendChild(errorItem(path, reason));
}

/** Whether any error is shown now.
 * @returns {boolean} */
export const hasErrors = () => Boolean($(".error-item"));
