// @ts-check
// Fly only what is on screen: the results are marked stale when the form (or sequence) is
// not the mission shown, and Fly is enabled only for a verified plan the fleet can fly,
// with the reason shown when it is not; the plan-to-fleet vehicle mapping beside it.
import { updateCommandButtons } from "./commands.js";
import { $, badge } from "./dom.js";
import { currentKey } from "./form.js";
import { fleet, flight, planning } from "./state.js";

/** Mark the results stale (and Fly disabled) unless they are the form's mission. */
export function refreshStale() {
  const shown = Boolean(planning.mission && planning.mission.plan);
  const key = planning.shownKey;
  let why = "";
  if (shown && planning.planning) why = "Planning the form's mission: the results below are the previous plan's.";
  else if (shown && planning.rejected) why = "The last plan request was rejected: the results below are an older mission's and cannot be flown.";
  else if (shown && currentKey(key) !== key) why = key && key.startsWith("seq:")
    ? "The sequence has changed since this plan: the results below are stale. Press Plan sequence to fly what it says."
    : "The form has changed since this plan: the results below are stale. Press Plan to fly what the form says.";
  planning.stale = Boolean(why);
  $("#stale-banner").textContent = why;
  $("#stale-banner").hidden = !why;
  $("#fly-panel").classList.toggle("stale", planning.stale);
  updateFlyButton();
}

/** Which plan vehicle flies on which fleet vehicle; the ones missing; the fleet's idle ones.
 * @returns {{planIds: string[], pairs: string[][], missing: string[], spare: string[]}} */
export function vehicleMapping() {
  const plan = planning.mission && planning.mission.plan;
  const planIds = plan ? plan.vehicles.map((v) => v.id) : [];
  const f = fleet.fleet;
  if (!f || !f.vehicles) return { planIds, pairs: [], missing: planIds, spare: [] };
  if (f.kind === "mock") {
    // The mock fleet is set down under the plan's starts and takes the plan's ids; one that
    // grows (serve --mock auto) adds the mocks a plan needs, up to grows_to.
    const n = Math.min(planIds.length, Math.max(f.vehicles, f.grows_to || 0));
    return { planIds, pairs: planIds.slice(0, n).map((id, i) => [id, `mock ${i + 1}`]),
             missing: planIds.slice(n), spare: [] };
  }
  const ids = f.ids || [];
  return { planIds, pairs: planIds.filter((id) => ids.includes(id)).map((id) => [id, id]),
           missing: planIds.filter((id) => !ids.includes(id)),
           spare: ids.filter((id) => !planIds.includes(id)) };
}

/** A list of ids, shortened past a dozen ("a, b, … and 30 more").
 * @param {string[]} ids
 * @param {number} [max] */
function idList(ids, max = 12) {
  return ids.length <= max ? ids.join(", ") : `${ids.slice(0, max).join(", ")}, … and ${ids.length - max} more`;
}

function showMapping() {
  const box = $("#mapping");
  box.textContent = "";
  if (!planning.mission || !planning.mission.plan || !fleet.fleet) return;
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
  const added = fleet.fleet.kind === "mock" ? m.pairs.length - fleet.fleet.vehicles : 0;
  if (added > 0) box.append(` · ${added} mock vehicle${added > 1 ? "s" : ""} added at Fly`);
}

/** Why Fly is disabled now, or null if the mission on screen can fly.
 * @returns {string | null} */
export function flyBlocker() {
  const mission = planning.mission;
  if (!mission || !mission.plan) return "plan a mission first";
  if (planning.planning) return "planning…";
  if (planning.rejected) return "the last plan request was rejected: fix the form and plan again";
  if (planning.stale) return "the form has changed: press Plan to fly what it says";
  if (!mission.plan_ok) return "the plan is not verified: it cannot be flown";
  if (flight.active) return "a flight is under way";
  const f = fleet.fleet;
  const needed = mission.plan.vehicles.length;
  if (!f || !f.vehicles) {
    return `no fleet configured: start the service with ${needed} mock vehicles ` +
      `(fleetplan serve --mock ${needed}) or a fleet file (fleetplan serve --fleet FLEET.json)`;
  }
  if (f.flying) return `flight ${f.flying} is under way`;
  const missing = vehicleMapping().missing;
  if (missing.length && f.grows_to) {
    return `the plan has ${needed} vehicles, more than the mock fleet may grow to ` +
      `(${f.grows_to}, setting mock_max_vehicles): restart the service with ` +
      `FLEETPLAN_MOCK_MAX_VEHICLES=${needed} (or fleetplan serve --mock ${needed}) ` +
      "or a fleet file naming them (fleetplan serve --fleet FLEET.json)";
  }
  if (missing.length) {
    return `${missing.length} plan vehicle${missing.length > 1 ? "s are" : " is"} not in the fleet ` +
      `of ${f.vehicles}: restart the service with ${needed} mock vehicles (fleetplan serve --mock ${needed}) ` +
      "or a fleet file naming them (fleetplan serve --fleet FLEET.json)";
  }
  return null;
}

/** Fly, its reason, the mapping and the flight's command buttons, from the state now. */
export function updateFlyButton() {
  const why = flyBlocker();
  $("#fly-button").disabled = Boolean(why);
  $("#fly-reason").textContent = why || "";
  showMapping();
  updateCommandButtons();
}
