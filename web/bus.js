// @ts-check
// The page's events between views: a view announces what changed, and the views that
// redraw after it subscribe here, so no view imports the ones it makes redraw (which is how
// the page's modules stay free of import cycles, tests/web/test_modules.py).

/** What changed, by event name:
 * - FLEET_CHANGED: the fleet's vehicles or the service's per-vehicle commands;
 * - FLIGHT_STARTED (detail: the flight, as POST .../flights answered): Fly started a flight;
 * - FLIGHT_CHANGED (detail: its status): the status of the flight followed changed;
 * - FLIGHT_ENDED (detail: its status and summary): the flight shown has ended;
 * - MISSION_SHOWN (detail: the mission's id): a mission's plan is on screen;
 * - MISSIONS_CHANGED: a mission finished planning (the stored missions changed);
 * - REPLAN_CHANGED: the plans the flight shown flew changed (the views' plan replaced). */
export const FLEET_CHANGED = "fleet-changed";
export const FLIGHT_STARTED = "flight-started";
export const FLIGHT_CHANGED = "flight-changed";
export const FLIGHT_ENDED = "flight-ended";
export const MISSION_SHOWN = "mission-shown";
export const MISSIONS_CHANGED = "missions-changed";
export const REPLAN_CHANGED = "replan-changed";

const bus = new EventTarget();

/** Announce `name`; its subscribers run now, in the order they subscribed.
 * @param {string} name
 * @param {unknown} [detail] */
export function emit(name, detail) {
  bus.dispatchEvent(new CustomEvent(name, { detail }));
}

/** Run `handler` with the event's detail each time `name` is announced.
 * @param {string} name
 * @param {(detail: any) => void} handler */
export function on(name, handler) {
  bus.addEventListener(name, (ev) => handler(/** @type {CustomEvent} */ (ev).detail));
}
