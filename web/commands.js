// @ts-check
// The flight's and the fleet's controls: which control endpoints this service has (from its
// OpenAPI description; buttons for the others stay hidden), pause and resume of the flight
// shown, fleet and per-vehicle commands, and what each answered.
import { api, unavailable } from "./api.js";
import { $, $$ } from "./dom.js";
import { showVehicleTable } from "./fleettable.js";
import { fleet, flight } from "./state.js";

/** Read the service's control endpoints; show the buttons it has. */
export async function loadCapabilities() {
  const { ok, data } = await api("GET", "/openapi.json");
  if (!ok || !data.paths) return;
  const posts = new Set(Object.entries(data.paths).filter(([, ops]) => ops && ops.post)
    .map(([path]) => path.replace(/\{[^}]+\}/g, "{}")));
  fleet.caps = {
    pause: posts.has("/api/flights/{}/pause"),
    resume: posts.has("/api/flights/{}/resume"),
    replan: posts.has("/api/flights/{}/replan"),
    fleetCommands: posts.has("/api/fleet/commands"),
    vehicleCommands: posts.has("/api/vehicles/{}/commands"),
  };
  for (const el of $$("[data-cap]")) el.hidden = !fleet.caps[/** @type {keyof import("./state.js").Capabilities} */ (el.dataset.cap)];
  updateCommandButtons();
  showVehicleTable();
}

/** Pause while the flight shown runs, Resume while it is paused, neither while one of
 * them is on its way; fleet commands whenever there is a fleet. */
export function updateCommandButtons() {
  const idle = flight.active && !flight.commandPending;
  $("#pause-button").disabled = !(idle && !flight.paused);
  $("#resume-button").disabled = !(idle && flight.paused);
  const has = Boolean(fleet.fleet && fleet.fleet.vehicles);
  for (const b of $$(".fleet-commands button")) b.disabled = !has;
}

/** @param {string} text @param {boolean} good */
function commandResult(text, good) {
  const el = $("#command-result");
  el.textContent = text;
  el.className = good ? "ok" : "bad";
}

/** Pause or resume the flight shown; its buttons follow the service's answer.
 * @param {"pause" | "resume"} which */
export async function pauseOrResume(which) {
  const id = flight.id;
  if (!id || flight.commandPending) return;
  flight.commandPending = true;
  updateCommandButtons();
  const r = await api("POST", `/api/flights/${id}/${which}`);
  flight.commandPending = false;
  if (unavailable(r)) {
    fleet.caps[which] = false;
    $(`#${which}-button`).hidden = true;
    commandResult(`${which}: not available on this service`, false);
  } else if (!r.ok) {
    commandResult(`${which} refused (${r.status}): ${r.data.reason ?? ""}`, false);
  } else {
    if (id === flight.id) {
      flight.paused = which === "pause";
      // The status the service gives a paused flight, from its own answer (no copy here).
      if (which === "pause" && typeof r.data.status === "string") flight.pausedStatus = r.data.status;
    }
    commandResult(`${which}d`, true);
  }
  updateCommandButtons();
}

/** Send a command (hold, land, rtl) to every fleet vehicle.
 * @param {string} command */
export async function fleetCommand(command) {
  const ids = (fleet.fleet && fleet.fleet.ids) || fleet.vehicles.map((v) => v.id);
  const r = await api("POST", "/api/fleet/commands", { command, vehicles: ids, confirm: true });
  if (unavailable(r)) { fleet.caps.fleetCommands = false; $(".fleet-commands").hidden = true; commandResult(`${command}: not available on this service`, false); return; }
  commandResult(r.ok ? `${command} sent to ${ids.length} vehicles` : `${command} refused (${r.status}): ${r.data.reason ?? ""}`, r.ok);
}

/** Send a command to one vehicle (from its row in the fleet table).
 * @param {string} id
 * @param {string} command */
export async function vehicleCommand(id, command) {
  const r = await api("POST", `/api/vehicles/${encodeURIComponent(id)}/commands`, { command, confirm: true });
  if (unavailable(r)) { fleet.caps.vehicleCommands = false; showVehicleTable(); commandResult(`${command}: not available on this service`, false); return; }
  commandResult(r.ok ? `${command} sent to ${id}` : `${command} ${id} refused (${r.status}): ${r.data.reason ?? ""}`, r.ok);
}
