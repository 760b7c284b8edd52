// The fleet table's health cells: text, level (ok, warn, bad) and a title per value, from
// what GET /api/vehicles reports. Tolerant of the shapes the planned fields may take.
"use strict";

const fmt1 = (x) => Number(x.toFixed(1)).toString();

// Link colours from the heartbeat age (s): PX4 sends 1 Hz heartbeats.
const LINK_OK_S = 1.5, LINK_WARN_S = 3.0;

export function linkLevel(v) {
  const age = v.heartbeat_age;
  if (age === null || age === undefined) return "bad";
  return age <= LINK_OK_S ? "ok" : (age <= LINK_WARN_S ? "warn" : "bad");
}

// Battery: a fraction (0..1), a percentage, or {remaining (0..1) | percent, voltage}.
export function batteryCell(b) {
  if (b === null || b === undefined) return ["–", ""];
  let pct = typeof b === "number" ? (b <= 1 ? b * 100 : b) : null;
  if (typeof b === "object") pct = b.percent ?? (typeof b.remaining === "number" ? b.remaining * 100 : null);
  const volts = typeof b === "object" && b.voltage !== undefined && b.voltage !== null ? `${fmt1(b.voltage)} V` : "";
  if (pct === null) return [volts || "–", "", ""];
  return [`${Math.round(pct)} %`, pct >= 35 ? "ok" : (pct >= 20 ? "warn" : "bad"), volts];
}

// MAVLink GPS_FIX_TYPE names; 3 (3D fix) and better are good enough to fly.
const GPS_FIX = ["no GPS", "no fix", "2D", "3D", "DGPS", "RTK float", "RTK fixed", "static", "PPP"];

// GPS: {fix_type (GPS_FIX_TYPE), satellites} or a word.
export function gpsCell(g) {
  if (g === null || g === undefined) return ["–", "", ""];
  if (typeof g !== "object") return [String(g), /^(ok|3d|rtk)/i.test(String(g)) ? "ok" : "warn", ""];
  const fix = g.fix_type ?? g.fix;
  const sats = g.satellites ?? g.satellites_visible;
  const name = typeof fix === "number" ? (GPS_FIX[fix] ?? `fix ${fix}`) : (fix ?? "");
  const count = sats !== undefined && sats !== null ? ` ${sats}` : "";
  return [`${name}${count}`.trim() || "–", typeof fix === "number" ? (fix >= 3 ? "ok" : "bad") : "",
          `${name} fix${count ? `, ${sats} satellites` : ""}`];
}

// Health: true/false, a word, or {ok, failures: [...]}.
export function healthCell(h, fault) {
  if (fault) return [String(fault), "bad"];
  if (h === null || h === undefined) return ["–", ""];
  if (typeof h === "boolean") return [h ? "ok" : "fault", h ? "ok" : "bad"];
  if (typeof h !== "object") return [String(h), /^ok$/i.test(String(h)) ? "ok" : "warn"];
  const failures = h.failures || h.failing || [];
  const good = h.ok ?? failures.length === 0;
  return [good ? "ok" : (failures.join(", ") || "fault"), good ? "ok" : "bad"];
}
