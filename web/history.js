// @ts-check
// History: the missions list (with their flights' badges), a mission's flights, and a
// finished flight reopened: its summary, events, and its replay (replay.js). Both lists
// redraw when a flight starts, changes status or ends, and when a mission is shown.
import { api, rowsOf } from "./api.js";
import { FLIGHT_CHANGED, FLIGHT_ENDED, FLIGHT_STARTED, MISSIONS_CHANGED, MISSION_SHOWN, on } from "./bus.js";
import { $, $$, fmt } from "./dom.js";
import { fillForm } from "./editor.js";
import { followFlight, isLive, logEvent, setFlightStatus, showFlightSummary } from "./flight.js";
import { clearFlightView, stopPlay } from "./flyscreen.js";
import { formKey } from "./form.js";
import { closePlanStream, showMission } from "./planning.js";
import { showFlownPlans } from "./replan.js";
import { startReplay } from "./replay.js";
import { editor, flight, planning } from "./state.js";

/** A status badge for a flight: green completed, neutral while flying, red otherwise.
 * @param {any} doc
 * @returns {HTMLSpanElement} */
function flightBadge(doc) {
  const span = document.createElement("span");
  span.className = `status-badge ${isLive(doc) ? "live" : (doc.summary && doc.summary.completed ? "good" : "poor")}`;
  span.textContent = doc.status;
  return span;
}

/** Most flights a mission's list shows (the API's largest page). */
const FLIGHTS_LISTED = 500;

/** The flights of the mission shown, newest first: summaries only, a flight's events are
 * fetched when it is opened.
 * @param {string} missionId */
export async function loadFlights(missionId) {
  const { ok, data } = await api("GET", `/api/flights?mission_id=${encodeURIComponent(missionId)}&limit=${FLIGHTS_LISTED}`);
  const list = $("#flight-list");
  if (!ok || !planning.mission || planning.mission.id !== missionId) return;
  list.innerHTML = "";
  const flights = rowsOf(data, "flights");
  if (!flights.length) {
    const li = document.createElement("li");
    li.className = "muted";
    li.textContent = "not flown yet";
    list.appendChild(li);
    return;
  }
  for (const e of flights) {
    const li = document.createElement("li");
    li.dataset.id = e.id;
    li.dataset.status = e.status;
    li.classList.toggle("selected", e.id === flight.id);
    const when = new Date(e.created_at).toLocaleTimeString();
    li.append(flightBadge(e), ` ${e.id} · ${when}`);
    if (e.summary && e.summary.goal_error_max !== undefined) li.append(` · goal error ${fmt(e.summary.goal_error_max, 2)} m`);
    li.title = isLive(e) ? "flying: follow it" : "reopen: summary, events, replay";
    li.addEventListener("click", () => openFlight(e.id));
    list.appendChild(li);
  }
  if (data.total > flights.length) {
    const li = document.createElement("li");
    li.className = "muted";
    li.textContent = `${data.total - flights.length} older flights not listed`;
    list.appendChild(li);
  }
}

/** Reopen a flight: follow it while it flies, else its summary, events and replay.
 * @param {string} id */
async function openFlight(id) {
  const { ok, data } = await api("GET", `/api/flights/${id}`);
  if (!ok) return;
  if (isLive(data)) { followFlight(data); return; }
  if (flight.active) return;  // the flight under way keeps the screen
  stopPlay();
  flight.id = id;
  clearFlightView();
  setFlightStatus(data.status, Boolean(data.summary && data.summary.completed));
  showFlightSummary(data);
  $$("#flight-list li").forEach((li) => li.classList.toggle("selected", li.dataset.id === id));
  let events = data.events;
  let record = null;
  if (data.has_record !== false) {
    const r = await api("GET", `/api/flights/${id}/record`);
    if (r.ok) record = r.data;
  }
  if (!events && record) events = record.events;
  $("#event-log").innerHTML = "";
  for (const e of events || []) logEvent(e);
  if (!record) return;
  // A replanned flight is replayed against the plans it flew.
  if ((record.replans || []).some((/** @type {any} */ r) => r.plan)) await showFlownPlans(id);
  startReplay(id, record);
}

/** The missions list and the flights of the mission shown (their badges follow a flight). */
function refreshLists() {
  refreshMissionList();
  if (planning.mission) loadFlights(planning.mission.id);
}

on(FLIGHT_STARTED, refreshLists);
on(FLIGHT_CHANGED, refreshLists);
on(FLIGHT_ENDED, refreshLists);
on(MISSIONS_CHANGED, refreshMissionList);
on(MISSION_SHOWN, loadFlights);

/** The missions list: name, size, plan status, flights (the latest one's badge). */
export async function refreshMissionList() {
  const [missions, flights] = await Promise.all([
    api("GET", "/api/missions?limit=30"), api("GET", "/api/flights"),
  ]);
  if (!missions.ok) return;
  // Flights per mission, newest first (the flights list is newest first).
  /** @type {Map<string, any[]>} */
  const byMission = new Map();
  for (const e of flights.ok ? rowsOf(flights.data, "flights") : []) {
    if (!byMission.has(e.mission_id)) byMission.set(e.mission_id, []);
    byMission.get(e.mission_id)?.push(e);
  }
  const list = $("#mission-list");
  list.innerHTML = "";
  for (const m of rowsOf(missions.data, "missions")) {
    const li = document.createElement("li");
    li.dataset.id = m.id;
    li.classList.toggle("selected", Boolean(planning.mission && planning.mission.id === m.id));
    const when = new Date(m.created_at).toLocaleString();
    const name = document.createElement("b");
    name.textContent = m.name;
    const plan = m.plan_status ? (m.plan_ok ? "verified" : `${m.plan_status}, not verified`) : m.status;
    li.append(name, ` · ${m.vehicle_count} vehicles · ${plan} · `);
    const flown = byMission.get(m.id) || (m.flights ? null : []);
    const count = flown ? flown.length : m.flights.count;
    const flightsSpan = document.createElement("span");
    flightsSpan.className = "flight-count";
    flightsSpan.textContent = count ? `${count} flight${count > 1 ? "s" : ""} ` : "not flown ";
    li.append(flightsSpan);
    if (flown && flown.length) li.append(flightBadge(flown[0]));
    const small = document.createElement("span");
    small.className = "muted small";
    small.textContent = ` ${when}`;
    li.append(small);
    li.addEventListener("click", () => openMission(m.id));
    list.appendChild(li);
  }
}

/** A mission from the list: into the form, and shown.
 * @param {string} id */
async function openMission(id) {
  const got = await api("GET", `/api/missions/${id}`);
  if (!got.ok) return;
  closePlanStream();
  fillForm(got.data.scenario);
  editor.presetName = null;
  planning.rejected = false;
  showMission(id, formKey());
}
