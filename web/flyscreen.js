// @ts-check
// The fly screen's view of time: the top-down view (planned paths, where each vehicle should
// be at the slider's time, where it is live or replayed), the time slider with its clock
// and progress bar, and ▶ to play the plan.
import { REPLAN_CHANGED, on } from "./bus.js";
import { $, clamp, color, colorOf, fmt } from "./dom.js";
import { drawMoving, drawStatic, latLonText } from "./flyview.js";
import { linkLevel } from "./health.js";
import { showFlown, showPlannedNow } from "./planview.js";
import { drawGoalMarkers, resetReplan } from "./replan.js";
import { fleet, flight, planning, views } from "./state.js";
import { lightAt, sampleAt } from "./tracks.js";

/** The fleet's geodetic origin, if its fleet file gives one. */
export const origin = () => (fleet.fleet && fleet.fleet.world_origin) || null;

/** Draw the plan's part of the fly view (workspace, paths, scale, corners), then the rest. */
export function drawFlyStatic() {
  const mission = planning.mission;
  if (!views.traj || !mission || !mission.plan) return;
  const scenario = mission.plan.scenario;
  const lim = scenario.limits;
  const o = origin();
  views.flyTf = drawStatic($("#fly-view"), {
    lo: lim.position_min, hi: lim.position_max, origin: o,
    obstacles: scenario.obstacles ?? [], clearance: scenario.obstacle_clearance ?? scenario.min_separation / 2,
    paths: views.traj.vehicles.map((v, i) => ({ id: v.id, color: color(i), points: v.position.map((p) => [p[0], p[1]]) })),
  });
  $("#geo-label").textContent = o
    ? `world origin ${latLonText(o)}, ${fmt(o.alt, 1)} m AMSL · x east, y north`
    : "x east, y north (m); no geodetic origin in the fleet file";
  drawFlyMoving();
  drawGoalMarkers();
}

/** Each planned vehicle's colour at plan time t: a show's light at t where the plan has a
 * light design, else the vehicle's own colour.
 * @param {import("./state.js").Trajectory} traj @param {number} t @returns {string[]} */
export function coloursAt(traj, t) {
  return traj.vehicles.map((v, i) => (v.lights ? lightAt(v.lights, t) : color(i)));
}

/** Where each vehicle is: the flight under way, or the replayed one at the slider's time
 * (in its light's colour then, for a show). */
function actualVehicles() {
  if (flight.replay) {
    const t = sliderTime();
    const traj = views.traj;
    const lit = traj ? coloursAt(traj, t) : [];
    /** @param {string} id */
    const colourOf = (id) => {
      const i = traj ? traj.vehicles.findIndex((v) => v.id === id) : -1;
      return i >= 0 ? lit[i] : colorOf(id, traj);
    };
    return flight.replay.vehicles.map((v) => ({
      id: v.id, color: colourOf(v.id), position: sampleAt(v.t, v.position, t),
      trail: v.position.filter((_, i) => v.t[i] <= t).map((p) => [p[0], p[1]]),
    }));
  }
  if (!flight.live) return [];
  return flight.live.vehicles.map((v) => ({
    id: v.id, color: colorOf(v.id, views.traj), position: v.position, velocity: v.velocity,
    trail: flight.trails[v.id], alert: Boolean(v.fault) || linkLevel(v) === "bad",
  }));
}

/** Draw what moves, in the top-down view and as the 3-D view's flown markers. */
export function drawFlyMoving() {
  const traj = views.traj;
  if (!views.flyTf || !traj) return;
  const k = Number($("#time-slider").value);
  const lit = coloursAt(traj, traj.t[k]);
  const planned = traj.vehicles.map((v, i) => ({ id: v.id, color: lit[i], position: v.position[k] }));
  const vehicles = actualVehicles();
  drawMoving($("#fly-view"), views.flyTf, { planned, vehicles });
  const shown = /** @type {{id: string, color: string, position: number[]}[]} */ (
    vehicles.filter((v) => v.position));
  showFlown(shown);
}

/** Forget the live flight's positions, phase and replans (the mission's own plan shown
 * again, if the views showed a replanned flight's). */
export function clearFlightView() {
  flight.live = null;
  flight.trails = {};
  $("#flight-phase").textContent = "";
  $("#flight-progress").value = 0;
  if (resetReplan()) { drawFlyStatic(); resetSlider(); }
}

/** The plan time (s) the slider is at. */
export const sliderTime = () => (views.traj ? views.traj.t[Number($("#time-slider").value)] : 0);
/** The plan's horizon (s). */
export const horizon = () => (views.traj ? views.traj.t[views.traj.t.length - 1] : 0);

/** Put every view at sample k of the plan.
 * @param {number} k */
export function setTime(k) {
  const traj = views.traj;
  if (!traj) return;
  showPlannedNow(traj.vehicles.map((v) => v.position[k]), coloursAt(traj, traj.t[k]));
  drawFlyMoving();
  showClock();
}

/** Set the slider to sample k (within its range) and every view with it.
 * @param {number} k */
export function moveSlider(k) {
  const slider = $("#time-slider");
  slider.value = clamp(k, 0, Number(slider.max));
  setTime(Number(slider.value));
}

/** A new plan on the slider: its samples, at the start. */
export function resetSlider() {
  if (!views.traj) return;
  const slider = $("#time-slider");
  slider.max = views.traj.t.length - 1;
  slider.value = 0;
  setTime(0);
}

/** The time label and the progress bar: the flight's progress while one flies, else the slider. */
export function showClock() {
  const t = sliderTime(), end = horizon();
  const live = flight.active ? flight.live : null;
  const mt = live ? live.flight_time : null;
  let text;
  let fraction = end > 0 ? t / end : 0;
  if (live) {
    if (mt === null || mt === undefined) {
      text = `${live.phase} · plan not started`;
      fraction = 0;
    } else if (mt <= end) {
      text = `${live.phase} · t = ${mt.toFixed(1)} s of ${end.toFixed(1)} s`;
      fraction = mt / end;
    } else {
      text = `${live.phase} · plan flown (${end.toFixed(1)} s of ${end.toFixed(1)} s), ` +
        `+${(mt - end).toFixed(1)} s after its end`;
      fraction = 1;
    }
    if (mt !== null && mt !== undefined && Math.abs(Math.min(mt, end) - t) > 0.15) {
      text += ` · viewing t = ${t.toFixed(1)} s`;
    }
  } else if (flight.replay) {
    text = `replay of flight ${flight.replay.id} · t = ${t.toFixed(1)} s of ${end.toFixed(1)} s`;
  } else {
    text = `plan · t = ${t.toFixed(1)} s of ${end.toFixed(1)} s`;
  }
  $("#time-label").textContent = text;
  $("#flight-progress").value = Math.round(clamp(fraction, 0, 1) * 1000);
}

/** The play button's glyph, drawn as SVG (a font may lack ⏸ and show an empty box).
 * @param {boolean} playing */
export function playIcon(playing) {
  const button = $("#play");
  button.dataset.icon = playing ? "pause" : "play";
  button.title = playing ? "stop playing the plan" : "play the plan";
  button.innerHTML = playing
    ? '<svg viewBox="0 0 10 10" width="10" height="10" aria-hidden="true"><rect x="1.5" y="1" width="2.5" height="8" fill="currentColor"/><rect x="6" y="1" width="2.5" height="8" fill="currentColor"/></svg>'
    : '<svg viewBox="0 0 10 10" width="10" height="10" aria-hidden="true"><path d="M2 1 L9 5 L2 9 Z" fill="currentColor"/></svg>';
}

/** Play: the plan on the slider (loops); again to stop. */
export function togglePlay() {
  const traj = views.traj;
  if (!traj) return;
  if (views.playTimer) { stopPlay(); return; }
  playIcon(true);
  $("#follow").checked = false;
  const slider = $("#time-slider");
  views.playTimer = setInterval(() => {
    let k = Number(slider.value) + 1;
    if (k > Number(slider.max)) k = 0;
    slider.value = k;
    setTime(k);
  }, 1000 / traj.rate);
}

// The flight's plans changed (a replan switched in): the fly view draws them, at the slider's time.
on(REPLAN_CHANGED, () => {
  drawFlyStatic();
  setTime(Number($("#time-slider").value));
});

/** Stop playing; every view at the slider's time (a show-sized 3-D view is drawn only now). */
export function stopPlay() {
  const playing = views.playTimer;
  if (playing) clearInterval(playing);
  views.playTimer = null;
  playIcon(false);
  if (playing) setTime(Number($("#time-slider").value));
}
