// @ts-check
// The fleet table: one row per vehicle, the flight's telemetry (5 per second) merged with
// GET /api/vehicles (link, mode, battery, GPS, health), the newer winning, and per-vehicle
// command buttons.
import { FLEET_CHANGED, REPLAN_CHANGED, on } from "./bus.js";
import { vehicleCommand } from "./commands.js";
import { $, colorOf } from "./dom.js";
import { batteryCell, gpsCell, healthCell, linkLevel, linkQualityCell } from "./health.js";
import { dropVehicle, isDropped, replanOffered } from "./replan.js";
import { fleet, flight, views } from "./state.js";

/** @typedef {import("./state.js").VehicleRow} VehicleRow */

/** @type {[string, string, (value: any) => string[]][]} */
const OPTIONAL_COLUMNS = [["autopilot", "autopilot", autopilotCell],
                          ["link_quality", "loss", linkQualityCell],
                          ["battery", "battery", batteryCell], ["gps", "GPS", gpsCell]];
// The autopilot a vehicle is flown as (GET /api/vehicles: "px4" or "ardupilot"; null unknown).
const AUTOPILOT_NAMES = { px4: "PX4", ardupilot: "ArduPilot" };
/** @param {any} a @returns {string[]} [text, level, title] */
function autopilotCell(a) {
  if (typeof a !== "string") return ["–", "", "autopilot not known yet"];
  const name = AUTOPILOT_NAMES[/** @type {"px4" | "ardupilot"} */ (a)] ?? a;
  return [name, "", `flown as ${name}`];
}
/** Most rows drawn: a show-sized fleet's table lists its vehicles with a fault first, then
 * the others up to this many, and says how many are not listed. */
export const TABLE_ROWS_MAX = 100;

/** Each vehicle's row from the flight's telemetry (phase, fault, tracking) and GET
 * /api/vehicles (link, battery, GPS, health), the newer source's fields winning where both
 * report one (mode, armed, position): a poll asked before the flight's last snapshot never
 * undoes it. After a flight its last snapshot (the fleet as the flight left it) stays until
 * a newer poll answers.
 * @returns {VehicleRow[]} */
function tableRows() {
  const live = flight.live;
  const polledNewer = fleet.vehiclesAt > flight.liveAt;
  if (!live || (!flight.active && polledNewer)) return fleet.vehicles;
  const byId = new Map(fleet.vehicles.map((v) => [v.id, v]));
  return live.vehicles.map((v) => {
    const polled = byId.get(v.id) || {};
    return polledNewer ? { ...v, ...polled } : { ...polled, ...v };
  });
}

/** Redraw the table from the fleet and the flight under way. */
export function showVehicleTable() {
  const rows = tableRows();
  // The autopilot column only where the fleet mixes autopilots (each row's vehicle cell names
  // its autopilot in its title either way), so a uniform fleet's table keeps its width.
  const mixed = new Set(rows.map((v) => v.autopilot).filter((a) => typeof a === "string")).size > 1;
  const optional = OPTIONAL_COLUMNS.filter(([key]) => (key === "autopilot" ? mixed
    : rows.some((v) => v[key] !== undefined && v[key] !== null)));
  const health = rows.some((v) => v.health !== undefined && v.health !== null);
  const actions = fleet.caps.vehicleCommands;
  const drops = replanOffered();
  /** @type {[string, string][]} [label, key] */
  const heads = [["vehicle", "id"], ["link", "link"], ["mode", "mode"], ["armed", "armed"],
                 ["alt", "alt"], ...optional.map((c) => /** @type {[string, string]} */ ([c[1], c[0]])),
                 ...(health ? [["health", "health"]] : []), ["phase", "phase"],
                 ...(drops ? [["replan", "replan"]] : []), ...(actions ? [["", "commands"]] : [])];
  const thead = $("#vehicle-state thead");
  const headHtml = `<tr>${heads.map(([h, key]) => `<th data-key="${key}">${h}</th>`).join("")}</tr>`;
  if (thead.innerHTML !== headHtml) thead.innerHTML = headHtml;
  const tbody = $("#vehicle-state tbody");
  const listed = rows.length > TABLE_ROWS_MAX
    ? [...rows.filter((v) => v.fault), ...rows.filter((v) => !v.fault)].slice(0, TABLE_ROWS_MAX)
    : rows;
  /** @type {Map<string, HTMLTableRowElement>} */
  const shown = new Map();
  for (const tr of /** @type {HTMLTableRowElement[]} */ (Array.from(tbody.querySelectorAll("tr[data-id]")))) {
    shown.set(tr.dataset.id ?? "", tr);
  }
  /** @type {HTMLTableRowElement[]} */
  const wanted = listed.map((v) => {
    const fresh = vehicleRow(v, optional, health, drops, actions);
    const old = shown.get(v.id);
    return old ? patchRow(old, fresh) : fresh;
  });
  if (listed.length < rows.length) {
    const tr = document.createElement("tr");
    tr.className = "more-vehicles";
    const td = document.createElement("td");
    td.colSpan = heads.length;
    td.textContent = `… and ${rows.length - listed.length} more vehicles (${rows.length} in all)`;
    tr.appendChild(td);
    const old = /** @type {HTMLTableRowElement | null} */ (tbody.querySelector("tr.more-vehicles"));
    wanted.push(old && old.outerHTML === tr.outerHTML ? old : tr);
  }
  const current = Array.from(tbody.children);
  if (current.length !== wanted.length || current.some((tr, i) => tr !== wanted[i])) {
    tbody.replaceChildren(...wanted);
  }
}

// The fleet changed, or the vehicles a replan dropped: the table shows them.
on(FLEET_CHANGED, showVehicleTable);
on(REPLAN_CHANGED, showVehicleTable);

/** `old` made to show what `fresh` (the same vehicle's row, just built) shows, cell by cell:
 * a cell that did not change is kept, so a button under the operator's pointer is the same
 * element from press to release and a click on it is never lost to a telemetry redraw
 * (5 a second). `fresh` itself when the columns changed.
 * @param {HTMLTableRowElement} old @param {HTMLTableRowElement} fresh
 * @returns {HTMLTableRowElement} */
function patchRow(old, fresh) {
  if (old.children.length !== fresh.children.length) return fresh;
  if (old.className !== fresh.className) old.className = fresh.className;
  for (const [i, cell] of Array.from(fresh.children).entries()) {
    const was = old.children[i];
    if (was.outerHTML !== cell.outerHTML) was.replaceWith(cell);
  }
  return old;
}

/** @param {VehicleRow} v
 * @param {[string, string, (value: any) => string[]][]} optional
 * @param {boolean} health
 * @param {boolean} drops  a Drop button (replan the flight without this vehicle)
 * @param {boolean} actions
 * @returns {HTMLTableRowElement} */
function vehicleRow(v, optional, health, drops, actions) {
  const tr = document.createElement("tr");
  tr.dataset.id = v.id;
  /** @param {string} text @param {string} [level] @param {string} [key] */
  const cell = (text, level, key) => {
    const td = document.createElement("td");
    td.textContent = text;
    if (level) td.className = `cell-${level}`;
    if (key) td.dataset.key = key;
    tr.appendChild(td);
    return td;
  };
  const name = cell("", "", "id");
  if (typeof v.autopilot === "string") name.title = `${v.id}: ${autopilotCell(v.autopilot)[2]}`;
  const dot = document.createElement("span");
  dot.className = "swatch";
  dot.style.background = colorOf(v.id, views.traj);
  name.append(dot, v.id);
  const age = v.heartbeat_age;
  const link = cell(age === null || age === undefined ? "no link" : `${age.toFixed(1)} s`, linkLevel(v), "link");
  link.title = `heartbeat age${v.link ? ` (${v.link})` : ""}`;
  // PX4's AUTO.* modes by their short names (LOITER, LAND, RTL): the full name in the title.
  cell(v.mode ? v.mode.replace(/^AUTO\./, "") : "–", v.mode ? "" : "warn", "mode").title = v.mode ?? "";
  cell(v.armed === null || v.armed === undefined ? "–" : (v.armed ? "armed" : "no"),
    v.armed ? "armed" : "", "armed").title = v.armed ? "armed" : "disarmed";
  const position = v.position;
  const alt = position ? `${position[2].toFixed(1)} m` : "–";
  cell(alt, "", "alt").title = position ? `world ${position.map((x) => x.toFixed(2)).join(", ")} m` +
    (v.tracking_error === null || v.tracking_error === undefined ? "" : ` · ±${v.tracking_error.toFixed(2)} m from plan`) : "";
  for (const [key, , render] of optional) {
    const [text, level, title] = render(v[key]);
    cell(text, level, key).title = title ?? "";
  }
  if (health) {
    const [text, level, title] = healthCell(v.health, v.fault);
    cell(text, level, "health").title = title ?? "";
  }
  cell(v.phase ?? "idle", v.fault ? "bad" : "", "phase").title = v.fault || "";
  if (drops) {
    const td = cell("", "", "replan");
    if (isDropped(v.id) || v.dropped) td.textContent = "dropped";
    else {
      const b = document.createElement("button");
      b.type = "button";
      b.className = "mini";
      b.textContent = "drop";
      b.title = `replan without ${v.id}: it lands (or holds, as chosen above) on its own path`;
      b.dataset.drop = v.id;
      b.addEventListener("click", () => dropVehicle(v.id));
      td.appendChild(b);
    }
  }
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
  return tr;
}
