// @ts-check
// What the page holds, one small record per view. Each view module owns its record's
// writes; the others read it. Shapes of the service's JSON are typed only as far as the page
// reads them.

/** @typedef {[number, number, number]} Vec3 */
/** @typedef {{id: string, start: (number | null)[], goal: (number | null)[]}} ScenarioVehicle
 *  (null: an input left empty) */
/** @typedef {{name?: string, dt: number, steps: number | string, min_separation: number,
 *   limits: Record<string, any>, vehicles: ScenarioVehicle[], separation_scale?: number[],
 *   [key: string]: any}} Scenario */
/** @typedef {{id: string, t: number[], thrust: number[]}} PlanVehicle */
/** @typedef {{method: string, outcome: string, reason: string, seconds: number}} Attempt
 *  one planning method tried or declined */
/** @typedef {{status: string, message?: string, solver?: string, scenario: Scenario,
 *   vehicles: PlanVehicle[], verification?: any, iterations?: any[], timing: any,
 *   sequence?: any, horizon?: any,
 *   method?: string | null, attempts?: Attempt[]}} Plan */
/** @typedef {{id: string, name: string, status: string, plan: Plan | null, plan_ok: boolean,
 *   plan_status?: string, scenario: Scenario, error?: {field?: string, reason: string}}} Mission */
/** @typedef {{rate: number, t: number[], vehicles: {id: string, position: number[][],
 *   velocity: number[][], lights?: [number, number, string][]}[]}} Trajectory
 *   GET /api/missions/{id}/trajectory (`lights`: a show's light changes) */
/** @typedef {{t: number[], d: number[], label?: string}} SeparationSeries */
/** @typedef {{id: string, position?: number[], velocity?: number[], fault?: string,
 *   phase?: string, heartbeat_age?: number | null, [key: string]: any}} VehicleRow */
/** @typedef {{id: number, status: string, requested_at: number, switch_time: number,
 *   planning_s: number | null, goals: Record<string, number[]>, drop: string[],
 *   drop_action: string, reason: string | null, why?: string}} ReplanObject
 *   an in-flight replan (POST /api/flights/{id}/replan, the live state's `replan`) */
/** @typedef {{flight_time?: number | null, phase: string, min_separation_live: number | null,
 *   vehicles: VehicleRow[], replan?: ReplanObject | null}} Telemetry  one `telemetry` event
 *   of a flight */
/** @typedef {{id: string, vehicles: {id: string, t: number[], position: number[][]}[]}} Replay */
/** @typedef {{kind?: string, vehicles?: number, ids?: string[], flying?: string | null,
 *   world_origin?: {lat: number, lon: number, alt: number}, grows_to?: number | null}} Fleet
 *   (grows_to: a mock fleet that adds the mocks a plan needs, up to this many) */
/** @typedef {{pause: boolean, resume: boolean, replan: boolean, fleetCommands: boolean,
 *   vehicleCommands: boolean}} Capabilities */
/** @typedef {Record<string, Record<string, string[]>>} StatusSets  GET /api/status `statuses` */

/** The service: its status sets (never a copy in the page) and the limits it checks requests
 * against, once GET /api/status answered.
 * @type {{statuses: StatusSets | null, limits: Record<string, number> | null}} */
export const service = { statuses: null, limits: null };

/** The editor: what the form holds beyond its inputs.
 * @type {{presetName: string | null, touched: boolean, selected: number, obstacle: number,
 *   extra: Record<string, unknown>, limitExtras: Record<string, unknown>,
 *   presetSettled: boolean}} */
export const editor = {
  presetName: null,     // name of the preset loaded, until the operator edits the form
  touched: false,       // the operator has typed in the form: nothing loads over it by itself
  selected: 0,          // vehicle row the top view places points for
  obstacle: -1,         // obstacle row selected (drawn bold), -1: none
  extra: {},            // scenario keys without inputs (separation_scale, ...), kept as loaded
  limitExtras: {},      // limits without inputs (thrust_min, thrust_max, body_rate_max)
  presetSettled: false, // the first preset has loaded (or could not be): the form is the page's
};

/** Planning: the mission shown and the request under way.
 * @type {{mission: Mission | null, shownKey: string | null, planning: boolean,
 *   pendingKey: string | null, rejected: boolean, stale: boolean,
 *   stream: EventSource | null, planningId: string | null, startedAt: number}} */
export const planning = {
  mission: null,     // the mission document shown (GET /api/missions/{id})
  shownKey: null,    // the form (or "seq:" + the sequence text) that mission was shown for
  planning: false,   // a plan request is being computed
  pendingKey: null,  // the form as sent with that request
  rejected: false,   // the last plan request was refused or failed
  stale: false,      // the results shown are not the form's mission
  stream: null,      // EventSource of the planning progress
  planningId: null,  // the mission being planned (what Cancel stops)
  startedAt: 0,      // when the plan request was sent (Date.now()), for the elapsed time
};

/** The plan's views: trajectories sampled for the plots, the slider and the fly view.
 * @type {{traj: Trajectory | null, sepTraj: Trajectory | null,
 *   sep: SeparationSeries | null, measured: SeparationSeries | null,
 *   flyTf: import("./flyview.js").ViewTransform | null,
 *   playTimer: ReturnType<typeof setInterval> | null}} */
export const views = {
  traj: null,      // /trajectory?rate=10 for the views and the slider
  sepTraj: null,   // /trajectory?rate=20 for the separation and speed plots
  sep: null,       // minimum pairwise separation over time (plan)
  measured: null,  // measured separation of the flight replayed
  flyTf: null,     // transform of the fly view
  playTimer: null,
};

/** The flight shown, live or replayed.
 * @type {{id: string | null, active: boolean, paused: boolean,
 *   pausedStatus: string | null, commandPending: boolean, stream: EventSource | null,
 *   live: Telemetry | null, trails: Record<string, number[][]>, drawPending: boolean,
 *   replay: Replay | null}} */
export const flight = {
  id: null,             // id of the flight shown (live or replayed)
  active: false,        // that flight is under way
  paused: false,        // its flight clock is stopped (by Pause)
  pausedStatus: null,   // the status the service gives a paused flight (from its pause answer)
  commandPending: false,// a pause or resume request is on its way
  stream: null,         // EventSource of the flight telemetry
  live: null,           // last telemetry snapshot of the flight under way
  liveAt: 0,            // when it arrived (performance.now(), ms)
  trails: {},           // id -> [[x, y]...] live positions so far
  drawPending: false,   // a frame is requested to draw the last snapshot
  replay: null,         // the finished flight replayed
};

/** The fleet: GET /api/vehicles and the control endpoints this service has.
 * @type {{vehicles: VehicleRow[], vehiclesAt: number, fleet: Fleet | null, caps: Capabilities}} */
export const fleet = {
  vehicles: [],
  vehiclesAt: 0,  // when the answer shown was asked for (performance.now(), ms)
  fleet: null,
  caps: { pause: false, resume: false, replan: false, fleetCommands: false, vehicleCommands: false },
};

/** The flight's replans (`replan.js`): goals being edited, and the plans flown on screen.
 * @type {{pending: Record<string, number[]>, drag: string | null, sending: boolean,
 *   current: ReplanObject | null, seen: string, drawn: string,
 *   dropped: Record<string, number>, planTraj: Trajectory | null}} */
export const replan = {
  pending: {},      // id -> [x, y, z]: goals dragged or typed, not sent yet
  drag: null,       // the vehicle whose goal marker is being dragged
  sending: false,   // a replan request is on its way
  current: null,    // the last replan object shown
  seen: "",         // "id:status" of the last replan object the snapshots carried
  drawn: "",        // the switched replans whose plans the views show ("1,2"; "" none)
  dropped: {},      // id -> flight time it was dropped at, in the plans shown
  planTraj: null,   // the mission's own trajectory while the views show the plans flown
};

/** The page holds its state: the service's status sets and the first preset (or the
 * operator's own typing). Until then Plan and the preset loader stay disabled.
 * @returns {boolean} */
export const ready = () => Boolean(service.statuses) && editor.presetSettled;

/** Whether a mission status has a role ("active": still planning, "failed") in the service's
 * own status sets; false until they are known.
 * @param {string} status
 * @param {string} role
 * @returns {boolean} */
export function missionIs(status, role) {
  const sets = service.statuses && service.statuses.mission;
  return Boolean(sets && sets[role] && sets[role].includes(status));
}
