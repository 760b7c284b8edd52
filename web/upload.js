// @ts-check
// Bring your own: a scenario, a formation sequence or a plan made elsewhere (`fleetplan plan`),
// pasted, chosen or dropped as JSON into one box; what kind of document it is, said before it
// is sent. The service takes all three at POST /api/missions (a plan is verified again there).
// A show tool's file (.skyc, or a ZIP of Skybrush CSVs) is read by the service into a sequence.
import { api, errorsOf } from "./api.js";
import { $ } from "./dom.js";
import { errorItem } from "./fielderrors.js";
import { refreshStale } from "./flygate.js";

/** @typedef {"plan" | "sequence" | "scenario"} DocumentKind */

/** What a document is, as the service tells them apart: null for none of them.
 * @param {unknown} doc
 * @returns {DocumentKind | null} */
export function documentKind(doc) {
  if (!doc || typeof doc !== "object" || Array.isArray(doc)) return null;
  const d = /** @type {Record<string, unknown>} */ (doc);
  const keys = Object.keys(d);
  if (keys.length === 1 && keys[0] === "plan") return documentKind(d.plan) === "plan" ? "plan" : null;
  if ("status" in d && "scenario" in d) return "plan";
  if ("formations" in d) return "sequence";
  if ("vehicles" in d) return "scenario";
  return null;
}

/** What the service does with each kind. */
const DOES = {
  plan: "verified again by the service and stored, ready to fly",
  sequence: "its legs planned in parallel, stitched and verified",
  scenario: "planned as it is",
};

/** The box's document, parsed: {doc} or {error}.
 * @returns {{doc?: unknown, error?: string}} */
export function boxDocument() {
  try { return { doc: JSON.parse($("#sequence-json").value) }; } catch (exc) {
    return { error: `not valid JSON: ${exc instanceof Error ? exc.message : exc}` };
  }
}

/** The line under the box: what it holds and what sending it does. */
export function describeBox() {
  const line = $("#sequence-kind");
  if (!$("#sequence-json").value.trim()) { line.textContent = ""; return; }
  const { doc } = boxDocument();
  const kind = documentKind(doc);
  const vehicles = kind === "plan" ? /** @type {any} */ (doc).plan?.vehicles ?? /** @type {any} */ (doc).vehicles
    : /** @type {any} */ (doc)?.vehicles;
  const count = Array.isArray(vehicles) ? `, ${vehicles.length} vehicles` : "";
  line.dataset.kind = kind ?? "";
  line.textContent = kind ? `a ${kind}${count}: ${DOES[kind]}` : "";
}

/** A show tool's file: a Skybrush compiled show or a ZIP of its per-drone CSV files, which
 * the service reads (POST /api/imports) into a formation sequence. */
const SHOW_FILE = /\.(skyc|zip)$/i;

/** A file's bytes in base64, as POST /api/imports takes them.
 * @param {File} file
 * @returns {Promise<string>} */
function base64Of(file) {
  return new Promise((resolve, reject) => {
    const reader = new FileReader();
    reader.onload = () => resolve(String(reader.result).replace(/^data:[^,]*,/, ""));
    reader.onerror = () => reject(reader.error);
    reader.readAsDataURL(file);
  });
}

/** A show file's formation sequence from the service, or null with its errors listed under
 * the box (each naming the file, line and column the service found wrong).
 * @param {File} file
 * @returns {Promise<string | null>} */
async function importedSequence(file) {
  const box = $("#sequence-error");
  box.innerHTML = "";
  $("#sequence-kind").textContent = `reading ${file.name}…`;
  const { ok, status, data } = await api("POST", "/api/imports",
    { file: await base64Of(file), filename: file.name });
  if (ok) return JSON.stringify(data, null, 2);
  describeBox();  // the box keeps what it held
  box.append(errorItem("file", `${file.name} was not imported (${status})`));
  for (const e of errorsOf(data)) box.append(errorItem(e.field || "", e.reason));
  return null;
}

/** A file into the box, the box opened: JSON as it is, a show file as the sequence the
 * service reads from it.
 * @param {File} file */
async function loadFile(file) {
  $("#sequence-panel").open = true;
  const text = SHOW_FILE.test(file.name) ? await importedSequence(file) : await file.text();
  if (text === null) return;
  $("#sequence-json").value = text;
  describeBox();
  refreshStale();
}

/** A file chosen with the file input.
 * @param {Event} ev */
export async function onFileChosen(ev) {
  const files = /** @type {HTMLInputElement} */ (ev.target).files;
  if (files && files[0]) await loadFile(files[0]);
}

/** A file dragged over the panel: it may be dropped there.
 * @param {DragEvent} ev */
export function onDragOver(ev) {
  if (!ev.dataTransfer || !Array.from(ev.dataTransfer.types).includes("Files")) return;
  ev.preventDefault();
  ev.dataTransfer.dropEffect = "copy";
}

/** A file dropped on the panel: into the box.
 * @param {DragEvent} ev */
export async function onDrop(ev) {
  const file = ev.dataTransfer && ev.dataTransfer.files[0];
  if (!file) return;
  ev.preventDefault();
  await loadFile(file);
}
