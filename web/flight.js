// @ts-check
// The flight under way: Fly, its telemetry and events followed live (server-sent events,
// polling when the stream is lost), its status in the header, its summary once it ends, and
// Abort for every flight in the air.
import { api, rowsOf } from "./api.js";
import { FLIGHT_CHANGED, FLIGHT_ENDED, FLIGHT_STARTED, emit } from "./bus.js";
import { updateCommandButtons } from "./commands.js";
import { $, appendScrolled, badge, fmt } from "./dom.js";
import { fillForm } from "./editor.js";
import { showVehicleTable } from "./fleettable.js";
import { flyBlocker, updateFlyButton } from "./flygate.js";
import { clearFlightView, drawFlyMoving, moveSlider, showClock } from "./flyscreen.js";
import { formKey } from "./form.js";
import { showMission } from "./planning.js";
import { replanTelemetry, updateReplanControls } from "./replan.js";
import { closeReplay } from "./replay.js";
import { editor, fleet, flight, planning, views } from "./state.js";
import { closestPair } from "./tracks.js";

/** @typedef {import("./state.js").Telemetry} Telemetry */

const TRAIL_POINTS = 1500;   // live trail kept per vehicle (5 Hz: 5 minutes)

/** A flight is under way while it has no finish time.
 * @param {{finished_at?: string | null}} doc */
export const isLive = (doc) => !doc.finished_at;

/** Fly: start the mission on screen, if nothing blocks it. */
export async function fly() {
  if (flyBlocker()) return;  // the button is disabled then; a stale click does nothing
  const mission = /** @type {import("./state.js").Mission} */ (planning.mission);
  $("#fly-button").disabled = true;
  $("#event-log").innerHTML = "";
  $("#flight-summary").textContent = "";
  const { status, data } = await api("POST", `/api/missions/${mission.id}/flights`);
  if (status !== 201) {
    $("#flight-status").textContent = `refused (${status}): ${data.reason}`;
    $("#flight-status").className = "bad";
    updateFlyButton();
    return;
  }
  $("#follow").checked = true;
  followFlight(data);
  emit(FLIGHT_STARTED, data);
  $("#fly-screen").scrollIntoView({ block: "nearest" });
}

/** Follow a flight under way: its telemetry, events and status.
 * @param {any} doc  GET /api/flights/{id} */
export function followFlight(doc) {
  if (flight.stream) flight.stream.close();
  closeReplay();
  if (flight.id !== doc.id) { clearFlightView(); flight.pausedStatus = null; }
  flight.id = doc.id;
  flight.active = true;
  flight.paused = Boolean(flight.pausedStatus) && doc.status === flight.pausedStatus;
  setFlightStatus(doc.status);
  updateFlyButton();
  updateReplanControls();
  if (!planning.mission || planning.mission.id !== doc.mission_id) {
    showFlownMission(doc.mission_id);  // flown from elsewhere: show its plan
  }
  const source = new EventSource(`/api/flights/${doc.id}/events`);
  flight.stream = source;
  source.addEventListener("telemetry", (ev) => showTelemetry(JSON.parse(ev.data)));
  source.addEventListener("event", (ev) => logEvent(JSON.parse(ev.data)));
  source.addEventListener("status", (ev) => {
    const { status } = JSON.parse(ev.data);
    setFlightStatus(status);
    // Paused or not as the flight says (once a pause answer named the paused status): a
    // flight paused elsewhere, resumed, or aborting while paused sets the buttons right.
    if (flight.pausedStatus) { flight.paused = status === flight.pausedStatus; updateCommandButtons(); }
    emit(FLIGHT_CHANGED, status);  // the lists' badges follow
  });
  source.addEventListener("done", (ev) => {
    source.close();
    flight.stream = null;
    const done = JSON.parse(ev.data);
    flightEnded(done.status, done);
  });
  source.onerror = () => {  // stream lost: poll the flight instead
    source.close();
    if (flight.stream === source) flight.stream = null;
    setTimeout(() => pollFlight(doc.id), 1000);
  };
}

/** The flight shown has ended with `status`; `done` its summary.
 * @param {string} status
 * @param {any} done */
function flightEnded(status, done) {
  flight.active = false;
  flight.paused = false;
  setFlightStatus(status, Boolean(done && done.summary && done.summary.completed));
  showFlightSummary(done);
  showClock();
  showVehicleTable();
  updateReplanControls();
  updateFlyButton();
  emit(FLIGHT_ENDED, done);
}

/** Show the plan of a flight started elsewhere. A page with nothing planned yet takes that
 * mission into its form too; otherwise the operator's form is kept (and reads as stale).
 * @param {string} id */
async function showFlownMission(id) {
  if (planning.mission || planning.planning || editor.touched) { showMission(id, null); return; }
  const got = await api("GET", `/api/missions/${id}`);
  if (!got.ok) return;
  fillForm(got.data.scenario);
  editor.presetName = null;
  showMission(id, formKey());
}

/** Read a flight once: follow it while it flies, else show how it ended.
 * @param {string} id */
export async function pollFlight(id) {
  const { ok, data } = await api("GET", `/api/flights/${id}`);
  if (!ok) return;
  if (isLive(data)) {
    if (!(flight.active && flight.id === id && flight.stream)) followFlight(data);
  } else { flight.id = id; flightEnded(data.status, data); }
}

/** The flight's status line and the header banner. `good`: the finished flight completed
 * (from its summary); undefined while it flies.
 * @param {string} status
 * @param {boolean} [good] */
export function setFlightStatus(status, good) {
  const el = $("#flight-status");
  el.textContent = `flight ${flight.id}: ${status}`;
  el.dataset.status = status;
  el.className = flight.active || good === undefined ? "" : (good ? "ok" : "bad");
  $("#flight-banner").textContent = flight.active ? `✈ ${status}` : "";
  $("#flight-banner").title = flight.active ? `flight ${flight.id}` : "";
}

/** One telemetry snapshot: trails grow; drawn once per frame at most.
 * @param {Telemetry} t */
function showTelemetry(t) {
  flight.live = t;
  flight.liveAt = performance.now();
  replanTelemetry(t);
  for (const v of t.vehicles) {
    if (!v.position) continue;
    const trail = flight.trails[v.id] || (flight.trails[v.id] = []);
    trail.push([v.position[0], v.position[1]]);
    if (trail.length > TRAIL_POINTS) trail.splice(0, trail.length - TRAIL_POINTS);
  }
  // A slow machine skips frames instead of falling behind.
  if (!flight.drawPending) {
    flight.drawPending = true;
    requestAnimationFrame(() => { flight.drawPending = false; drawTelemetry(flight.live); });
  }
}

/** Draw a snapshot: the fleet table, the closest pair, the slider when it follows.
 * @param {Telemetry | null} t */
export function drawTelemetry(t) {
  if (!t) return;
  showVehicleTable();
  $("#flight-phase").textContent = separationLine(t);
  if ($("#follow").checked && views.traj && t.flight_time !== null && t.flight_time !== undefined) {
    moveSlider(Math.round(t.flight_time * views.traj.rate));
  } else {
    drawFlyMoving();
    showClock();
  }
}

/** The separation line: the closest pair now, from the vehicles' positions in this snapshot
 * (the plan's separation metric), beside the closest the flight has come so far (the
 * service's `min_separation_live`, a minimum over the flight, not a current value).
 * @param {Telemetry} t */
export function separationLine(t) {
  const scale = planning.mission?.plan?.scenario?.separation_scale ?? [1, 1, 1];
  const points = t.vehicles.map((v) => v.position).filter((p) => Array.isArray(p));
  const now = points.length > 1 ? `closest pair now ${closestPair(points, scale).toFixed(2)} m` : "";
  const sofar = t.min_separation_live === null || t.min_separation_live === undefined ? ""
    : `closest so far ${t.min_separation_live.toFixed(2)} m`;
  return [now, sofar].filter(Boolean).join(" · ");
}

/** An event's words: its kind, then its detail, without saying a word twice ("landed:
 * landed and disarmed" reads "landed and disarmed"; "land: landing" reads "landing").
 * @param {{kind: string, detail?: string | null}} e */
export function eventText(e) {
  const detail = (e.detail ?? "").trim();
  if (!detail) return e.kind;
  const kind = e.kind.replace(/_/g, " ").toLowerCase();
  return detail.toLowerCase().startsWith(kind) ? detail : `${e.kind}: ${detail}`;
}

/** One line of the event log.
 * @param {{t: number, vehicle?: string, kind: string, detail?: string}} e */
export function logEvent(e) {
  const li = document.createElement("li");
  li.textContent = `${fmt(e.t, 2)} s ${e.vehicle ? e.vehicle + ": " : ""}${eventText(e)}`;
  appendScrolled($("#event-log"), li);
}

/** A finished flight's summary line.
 * @param {any} done */
export function showFlightSummary(done) {
  const s = done.summary;
  const box = $("#flight-summary");
  box.textContent = "";
  if (done.error) box.append(badge(false, `${done.error} `));
  if (!s) return;
  box.append(badge(Boolean(s.completed), `completed: ${s.completed ? "yes" : "no"}`),
    ` · goal error max ${fmt(s.goal_error_max)} m · ${trackingText(s)} · ` +
    `measured min separation ${fmt(s.min_separation_measured)} m · setpoints ${fmt(s.setpoint_rate_hz, 1)} Hz, ` +
    `jitter p99 ${fmt(s.jitter_p99_ms, 2)} ms`);
}

/** The tracking error, with an abort told apart: judged up to the abort, the landing or
 * hold after it flown off the plan on purpose.
 * @param {any} s  a flight summary @returns {string} */
export function trackingText(s) {
  const tracking = `tracking error max ${fmt(s.tracking_error_max)} m`;
  if (s.aborted_at === null || s.aborted_at === undefined) return tracking;
  return `${tracking} up to the abort at t = ${fmt(s.aborted_at, 1)} s, ` +
    `then ${fmt(s.after_abort_s, 1)} s aborting (off the plan on purpose)`;
}

/** Abort the flight shown and any other one under way: this button must always work. */
export async function abortAll() {
  const { ok, data } = await api("GET", "/api/flights?active=true");
  const ids = new Set(ok ? rowsOf(data, "flights").map((e) => e.id) : []);
  if (flight.id && flight.active) ids.add(flight.id);
  if (fleet.fleet && fleet.fleet.flying) ids.add(fleet.fleet.flying);
  if (!ids.size) { $("#flight-banner").textContent = "nothing is flying"; return; }
  for (const id of ids) {
    const r = await api("POST", `/api/flights/${id}/abort`, { action: "land" });
    if (r.ok && id === flight.id) setFlightStatus(r.data.status);
  }
  updateCommandButtons();
}
