// @ts-check
// fleetplan browser page: enter a mission, plan it, inspect the plan, fly exactly the plan on
// screen, watch the fleet, reopen and replay past flights, abort. Plain JavaScript modules, no
// build step; they talk only to this service's /api (see /docs). This module wires the
// controls to the views and loads the page's state; Plan waits for that state.
import { fleetCommand, loadCapabilities, pauseOrResume } from "./commands.js";
import { $, $$ } from "./dom.js";
import { addObstacle, addVehicle, formEdited, loadExampleList, loadPreset, onTopViewClick, onTopViewPointerDown,
         onTopViewPointerMove, onTopViewPointerUp, presetChosen } from "./editor.js";
import { refreshStale } from "./flygate.js";
import { abortAll, drawTelemetry, fly } from "./flight.js";
import { setTime, togglePlay } from "./flyscreen.js";
import { buildLimitRows } from "./form.js";
import { refreshMissionList } from "./history.js";
import { submitPlan, submitSequence, updatePlanButtons } from "./planning.js";
import { cancelPlanning } from "./planprogress.js";
import { cancelGoals, onGoalPointerDown, onGoalPointerMove, onGoalPointerUp, sendGoals } from "./replan.js";
import { editor, flight } from "./state.js";
import { refreshStatus, refreshVehicles } from "./status.js";
import { describeBox, onDragOver, onDrop, onFileChosen } from "./upload.js";

const STATUS_EVERY_MS = 5000;
const VEHICLES_EVERY_MS = 2000;

function wire() {
  $("#scenario-form").addEventListener("submit", submitPlan);
  $("#scenario-form").addEventListener("input", formEdited);
  $("#sequence-plan").addEventListener("click", submitSequence);
  $("#plan-cancel").addEventListener("click", cancelPlanning);
  $("#sequence-file").addEventListener("change", onFileChosen);
  $("#sequence-json").addEventListener("input", () => { describeBox(); refreshStale(); });
  $("#sequence-panel").addEventListener("dragover", onDragOver);
  $("#sequence-panel").addEventListener("drop", onDrop);
  $("#preset").addEventListener("change", presetChosen);
  $("#preset-load").addEventListener("click", () => loadPreset());
  $("#add-vehicle").addEventListener("click", addVehicle);
  $("#top-view").addEventListener("click", onTopViewClick);
  $("#top-view").addEventListener("pointerdown", onTopViewPointerDown);
  $("#top-view").addEventListener("pointermove", onTopViewPointerMove);
  $("#top-view").addEventListener("pointerup", onTopViewPointerUp);
  $("#top-view").addEventListener("pointercancel", onTopViewPointerUp);
  $("#add-box").addEventListener("click", () => addObstacle("box"));
  $("#add-cylinder").addEventListener("click", () => addObstacle("cylinder"));
  $("#time-slider").addEventListener("input", (/** @type {Event} */ ev) => {
    $("#follow").checked = false;  // the operator looks elsewhere in time; "follow" brings it back
    setTime(Number(/** @type {HTMLInputElement} */ (ev.target).value));
  });
  $("#follow").addEventListener("change", () => drawTelemetry(flight.live));
  $("#play").addEventListener("click", togglePlay);
  $("#fly-button").addEventListener("click", fly);
  $("#pause-button").addEventListener("click", () => pauseOrResume("pause"));
  $("#resume-button").addEventListener("click", () => pauseOrResume("resume"));
  for (const b of $$(".fleet-commands button")) b.addEventListener("click", () => fleetCommand(b.dataset.command));
  $("#abort-button").addEventListener("click", abortAll);
  $("#fly-view").addEventListener("pointerdown", onGoalPointerDown);
  $("#fly-view").addEventListener("pointermove", onGoalPointerMove);
  $("#fly-view").addEventListener("pointerup", onGoalPointerUp);
  $("#fly-view").addEventListener("pointercancel", onGoalPointerUp);
  $("#replan-send").addEventListener("click", sendGoals);
  $("#replan-cancel").addEventListener("click", cancelGoals);
}

function start() {
  buildLimitRows();
  wire();
  updatePlanButtons();  // disabled until the status sets and the first preset are in
  refreshStatus();
  // The first preset fills the form, unless the operator started typing meanwhile.
  loadExampleList().then(() => loadPreset(true)).finally(() => {
    editor.presetSettled = true;
    updatePlanButtons();
  });
  loadCapabilities();
  refreshMissionList();
  refreshVehicles();
  setInterval(refreshStatus, STATUS_EVERY_MS);
  setInterval(refreshVehicles, VEHICLES_EVERY_MS);
}

if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
else start();
