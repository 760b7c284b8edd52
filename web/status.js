// @ts-check
// The service and fleet as the header and fleet table show them: GET /api/status (status
// sets, fleet, planning jobs) and GET /api/vehicles, polled; a flight started elsewhere is
// picked up from the fleet's `flying`.
import { api } from "./api.js";
import { FLEET_CHANGED, emit } from "./bus.js";
import { $ } from "./dom.js";
import { pollFlight } from "./flight.js";
import { updateFlyButton } from "./flygate.js";
import { drawFlyStatic, origin } from "./flyscreen.js";
import { updatePlanButtons } from "./planning.js";
import { fleet, flight, service } from "./state.js";

/** GET /api/vehicles into the fleet table (and a flight under way found). */
export async function refreshVehicles() {
  const asked = performance.now();  // the answer is at most as new as the question
  const { ok, data } = await api("GET", "/api/vehicles");
  if (!ok) return;
  fleet.vehicles = data.vehicles;
  fleet.vehiclesAt = asked;
  const hadOrigin = Boolean(origin());
  fleet.fleet = { ...(fleet.fleet || {}), ...data.fleet };
  if (Boolean(origin()) !== hadOrigin) drawFlyStatic();
  emit(FLEET_CHANGED);
  updateFlyButton();
  if (data.fleet.flying && data.fleet.flying !== flight.id && !flight.active) {
    pollFlight(data.fleet.flying);  // a flight started elsewhere: show it (and its Abort)
  }
}

/** GET /api/status into the header; the status sets every mission shown is judged by. */
export async function refreshStatus() {
  const { ok, data } = await api("GET", "/api/status");
  const el = $("#service-status");
  if (!ok) { el.textContent = "service unreachable"; el.className = "bad"; return; }
  el.className = "muted";
  service.statuses = data.statuses || service.statuses;
  if (data.limits) showLimits(data.limits);
  const f = data.fleet;
  const grows = f.grows_to ? ` (up to ${f.grows_to} as plans need)` : "";
  el.textContent = `${f.kind === "none" ? "no fleet" : `${f.vehicles} ${f.kind} vehicles${grows}`} · planning ${data.planning_jobs}`;
  el.title = `fleetplan ${data.version}: fleet ${f.kind}, ${data.planning_jobs} planning jobs`;
  fleet.fleet = { ...(fleet.fleet || {}), ...f };
  updateFlyButton();
  updatePlanButtons();
}

/** The server's limits, said before a request meets them: under the presets, and as the
 * generator's largest vehicle count.
 * @param {Record<string, number>} limits */
function showLimits(limits) {
  service.limits = limits;
  $("#preset-count").max = String(limits.max_vehicles);
  $("#server-limits").textContent = `This server plans up to ${limits.max_vehicles} vehicles, ` +
    `${limits.max_steps} steps, a ${limits.max_horizon_s} s horizon and ${limits.max_obstacles} ` +
    `obstacles per mission (its settings max_vehicles, max_steps, max_horizon_s, max_obstacles).`;
}
