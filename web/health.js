// @ts-check
// The fleet table's health cells: text, level (ok, warn, bad) and a title per value, from
// what GET /api/vehicles reports. Tolerant of the shapes the planned fields may take.
/** @param {number} x */
const fmt1 = (x) => Number(x.toFixed(1)).toString();

// Link colours from the heartbeat age (s): PX4 sends 1 Hz heartbeats.
const LINK_OK_S = 1.5, LINK_WARN_S = 3.0;

/** The link's level from its heartbeat age.
 * @param {{heartbeat_age?: number | null}} v
 * @returns {"ok" | "warn" | "bad"} */
export function linkLevel(v) {
  const age = v.heartbeat_age;
  if (age === null || age === undefined) return "bad";
  return age <= LINK_OK_S ? "ok" : (age <= LINK_WARN_S ? "warn" : "bad");
}

// Link quality, as GET /api/vehicles and the flight's telemetry report it (gcs.flight.link.quality):
// {received, lost, reordered, duplicates, loss_pct, recent_loss_pct (last 5 s), latency_ms,
// jitter_ms}. The loss of the last seconds is what the level judges (10 % and more: bad).
/** @param {any} q @returns {string[]} [text, level, title] */
export function linkQualityCell(q) {
  if (q === null || q === undefined || typeof q !== "object") return ["–", "", ""];
  const loss = q.recent_loss_pct ?? q.loss_pct;
  const pct = typeof loss === "number" ? `${loss < 10 ? loss.toFixed(1) : Math.round(loss)} %` : "–";
  const ms = typeof q.latency_ms === "number" ? `, latency ${Math.round(q.latency_ms)} ms` : "";
  const level = typeof loss !== "number" ? "" : (loss >= 10 ? "bad" : (loss >= 5 ? "warn" : "ok"));
  const jitter = typeof q.jitter_ms === "number" ? `, jitter ${fmt1(q.jitter_ms)} ms` : "";
  // The cell stays narrow (the fly screen's table docks beside the map): the loss; the rest
  // in its title.
  return [pct, level,
          `loss ${pct} over the last 5 s (${q.lost ?? 0} of ${(q.received ?? 0) + (q.lost ?? 0)} in all)${ms}, ` +
          `${q.reordered ?? 0} reordered, ${q.duplicates ?? 0} duplicates${jitter}`];
}

// Battery, as GET /api/vehicles reports it: {remaining_pct (0..100, null unknown), voltage}.
/** @param {any} b @returns {string[]} [text, level, title] */
export function batteryCell(b) {
  if (b === null || b === undefined) return ["–", ""];
  const pct = typeof b === "object" ? (b.remaining_pct ?? null) : null;
  const volts = typeof b === "object" && b.voltage !== undefined && b.voltage !== null ? `${fmt1(b.voltage)} V` : "";
  if (pct === null) return [volts || "–", "", ""];
  return [`${Math.round(pct)} %`, pct >= 35 ? "ok" : (pct >= 20 ? "warn" : "bad"), volts];
}

// MAVLink GPS_FIX_TYPE names; 3 (3D fix) and better are good enough to fly.
const GPS_FIX = ["no GPS", "no fix", "2D", "3D", "DGPS", "RTK float", "RTK fixed", "static", "PPP"];

// GPS, as GET /api/vehicles reports it: {fix_type (GPS_FIX_TYPE), satellites, h_acc, v_acc}.
/** @param {any} g @returns {string[]} [text, level, title] */
export function gpsCell(g) {
  if (g === null || g === undefined || typeof g !== "object") return ["–", "", ""];
  const fix = g.fix_type;
  const sats = g.satellites;
  const name = typeof fix === "number" ? (GPS_FIX[fix] ?? `fix ${fix}`) : "";
  const count = sats !== undefined && sats !== null ? ` ${sats}` : "";
  const acc = typeof g.h_acc === "number" ? `, ±${fmt1(g.h_acc)} m` : "";
  return [`${name}${count}`.trim() || "–", typeof fix === "number" ? (fix >= 3 ? "ok" : "bad") : "",
          `${name} fix${count ? `, ${sats} satellites` : ""}${acc}`];
}

// A PX4 pre-arm failure about the state estimate: the estimator still settling after boot.
const ESTIMATOR_TEXT = /estimat|\bekf\b|heading/i;
const PREFLIGHT_FAIL = /^preflight fail:\s*/i;

/** The health cell while the pre-arm check does not pass: the autopilot's own reason when it
 * gave one ("Preflight Fail: ..."), as "estimator settling" (amber) when every reason is the
 * estimate settling after boot (PX4 SITL and the mock for their first seconds), and "pre-arm
 * not ready" (amber) until it names one (PX4 says why when arming is asked).
 * @param {string[]} warnings @returns {string[]} [text, level, title] */
function prearmCell(warnings) {
  const failing = warnings.filter((w) => PREFLIGHT_FAIL.test(w));
  if (failing.length && failing.every((w) => ESTIMATOR_TEXT.test(w))) {
    return ["estimator settling", "warn", `the state estimate is settling after boot: ${failing.join("; ")}`];
  }
  if (failing.length) return [failing[failing.length - 1].replace(PREFLIGHT_FAIL, ""), "bad", warnings.join("; ")];
  return ["pre-arm not ready", "warn",
          "the autopilot's pre-arm check does not pass yet (an estimator settling after boot, " +
          "or a failure it names when arming is asked)"];
}

// Health, as GET /api/vehicles reports it: {unhealthy: [sensor names] (null unknown),
// prearm_ok (null unknown), warnings: [recent warning texts]}.
/** @param {any} h @param {string} [fault] @returns {string[]} [text, level, title] */
export function healthCell(h, fault) {
  if (fault) return [String(fault), "bad"];
  if (h === null || h === undefined || typeof h !== "object") return ["–", ""];
  const unhealthy = h.unhealthy || [];
  if (unhealthy.length) return [unhealthy.join(", "), "bad"];
  if (h.prearm_ok === false) return prearmCell(h.warnings || []);
  if (h.unhealthy === null || h.unhealthy === undefined) return ["–", ""];
  return (h.warnings || []).length ? ["warning", "warn"] : ["ok", "ok"];
}
