"""The flight record's summary: whether the flight completed, and the figures it is judged by.

`summarise` computes it from the recorded data (`gcs.flight.run.record`): tracking errors of
every position report during the flight against the plan at its receive time, up to an abort
if there was one (``aborted_at``, flight time; ``after_abort_s``, the time flown after it,
landing or holding off the plan on purpose); the measured minimum separation (the plan's
metric, diag(1/separation_scale)) from every vehicle's reports interpolated onto common
instants at the stream rate; the stream's rate and jitter; and the verdict with its reasons
(``completed``, ``why``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from gcs.documents import finite_or_none
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.run.record import FlightRecorder, gcs_time, plan_times
from gcs.flight.safety.margin import MarginCheck, separation_alarm_at
from gcs.flight.timeline.stream import jitter_stats
from gcs.phases import EventKind, VehiclePhase
from planner import Plan
from planner.verification.verify import SEPARATION_TOLERANCE

if TYPE_CHECKING:
    from gcs.flight.procedure.vehicle import VehicleStatus
    from planner.model.scenario import Scenario

__all__ = ["STALE_REPORT_S", "goal_tolerance", "measured_min_separation", "summarise"]


def measured_min_separation(times: list[np.ndarray], positions: list[np.ndarray],
                            t0: float, t1: float, rate: float,
                            scale: np.ndarray, *,
                            stale_after: float | None = None) -> tuple[float, float]:
    """Smallest pair distance in the metric ||diag(1/scale) d|| over [t0, t1]: each vehicle's
    reports are linearly interpolated onto common instants `rate` Hz apart. `stale_after`:
    a vehicle counts only up to this long after its last report (a lost link's last
    position is not where it is later). Returns (distance, instant); (inf, nan) with fewer
    than two vehicles or no overlap."""
    if len(times) < 2 or t1 <= t0:
        return math.inf, math.nan
    grid = np.arange(t0, t1, 1.0 / rate)
    tracks = []
    known = []
    for t, p in zip(times, positions, strict=True):
        if t.size < 2:
            return math.inf, math.nan
        tracks.append(np.stack([np.interp(grid, t, p[:, k]) for k in range(3)], axis=1))
        known.append(grid <= t[-1] + stale_after if stale_after is not None
                     else np.ones(len(grid), dtype=bool))
    stacked = np.stack(tracks) / scale  # (N, G, 3)
    i, j = np.triu_indices(len(tracks), k=1)
    d = np.linalg.norm(stacked[i] - stacked[j], axis=2)  # (pairs, G)
    valid = np.stack(known)
    # a stale pair does not count; a NaN report makes the answer NaN (unknown)
    d = np.where(valid[i] & valid[j], d, math.inf)
    pair, instant = np.unravel_index(int(np.argmin(d)), d.shape)
    if math.isinf(d[pair, instant]):
        return math.inf, math.nan
    return float(d[pair, instant]), float(grid[instant])


#: A vehicle's reports count this long after its last one in the measured separation (s).
STALE_REPORT_S = 1.0


def goal_tolerance(options: FlightOptions, position_error: float | None,
                   h_acc: float = math.nan) -> float:
    """How close to its goal a vehicle must end: max(goal_tolerance, goal_tolerance_k x the
    larger of the fleet's position_error and the vehicle's reported horizontal accuracy
    (GPS_RAW_INT h_acc, m; NaN when not reported))."""
    accuracy = max(position_error or 0.0, h_acc if math.isfinite(h_acc) else 0.0)
    return max(options.goal_tolerance, options.goal_tolerance_k * accuracy)


def summarise(recorder: FlightRecorder, plan: Plan, options: FlightOptions,
              vehicles: Sequence[VehicleStatus], *, flight_start: float | None,
              pauses: Sequence[Sequence[float | None]] = (), now: float,
              missed_ticks: int, lateness: Sequence[float] | None,
              error: BaseException | None, margin: MarginCheck | None = None,
              position_error: float | None = None,
              planned: Callable[[str, np.ndarray], np.ndarray] | None = None,
              horizon: float | None = None,
              off_plan: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The flight record's summary (see the module docstring) from what `recorder` holds and
    the executor's final view of each vehicle (fault, goal error, phase). `now` is the GCS-clock
    time at the end; `lateness` is None when nothing was streamed. `why` says in words why the
    flight is or is not complete.


    With in-flight replans: `planned(id, flight times)` is where a vehicle was meant to be
    (the flight's plans, `gcs.flight.timeline.flown`; default `plan`), `horizon` the end of the last
    plan flown (flight time; default the plan's), `off_plan` the flight time from which a
    vehicle flew off the plans (dropped: its tracking is judged up to there). A dropped
    vehicle is not judged against a goal; a faulty one the others were replanned around
    does not stop the flight from counting as completed for those that arrived."""
    scenario = plan.scenario
    horizon = scenario.horizon if horizon is None else horizon
    out = _summary_keys(recorder, scenario, options, vehicles, missed_ticks, margin,
                        goal_tolerance(options, position_error))
    why: list[str] = out["why"]
    if error is not None:
        why.append(f"{type(error).__name__}: {error}")
    if plan.verification is not None:
        out["min_separation_planned"] = plan.verification.min_separation_continuous
    if flight_start is None:
        why.append("the flight clock never started")
        return out
    t0 = flight_start
    end, t1 = _judged_window(recorder, options, vehicles, t0, horizon, pauses, now)
    # An abort leaves the plan on purpose (a landing or a hold): the tracking is judged up to
    # it, and the time flown after it is told apart.
    aborted = next((e["t"] for e in recorder.events if e["kind"] == EventKind.ABORT), None)
    tracked_until = t1 if aborted is None else min(t1, aborted)
    if aborted is not None:
        at = float(plan_times(np.array([aborted]), t0, pauses)[0])
        out["aborted_at"] = round(max(0.0, at), 3)
        out["after_abort_s"] = round(max(0.0, now - aborted), 3)
    tracking, times, positions = _tracking_errors(recorder, plan, vehicles, t0, pauses,
                                                  tracked_until, planned, off_plan or {})
    if tracking:
        out["tracking_error_max"] = max(tracking)
    # Separation over the whole flight, not only up to the first fault: a vehicle sent
    # down by land_faulty still passes the others.
    unknown = _separation_verdict(out, scenario, options, times, positions, t0, min(end, now))
    if lateness is not None:
        _stream_figures(out, recorder, vehicles, lateness, t0, t1)
    _verdict(out, scenario, options, vehicles, error, unknown)
    return out


def _summary_keys(recorder: FlightRecorder, scenario: Scenario, options: FlightOptions,
                  vehicles: Sequence[VehicleStatus], missed_ticks: int,
                  margin: MarginCheck | None, tolerance: float) -> dict[str, Any]:
    """Every key of the summary, in the contract's order: the figures known before the flight
    is measured, None for those `summarise` fills in from the recorded data."""
    # each vehicle's own: with the accuracy it reported when its goal error was measured
    tolerances = {v.id: v.goal_tolerance if math.isfinite(v.goal_tolerance) else tolerance
                  for v in vehicles}
    return {
        "completed": False, "why": [], "goal_error_max": None, "goal_tolerance": tolerance,
        "goal_tolerances": tolerances,
        "tracking_error_max": None, "aborted_at": None, "after_abort_s": None,
        "min_separation_measured": None, "min_separation_planned": None,
        "min_separation_required": scenario.min_separation - scenario.separation_margin,
        "separation_alarm_at": separation_alarm_at(scenario, options.separation_alarm),
        "goal_settle_s": round(recorder.goal_settle_s, 3),
        "separation_held": None,
        "separation_margin": None if margin is None else margin.to_dict(),
        "setpoint_rate_hz": None, "jitter_p50_ms": None, "jitter_p99_ms": None,
        "missed_ticks": missed_ticks,
        "faults": {v.id: v.fault for v in vehicles if v.fault is not None},
        "dropped": {v.id: {"action": v.dropped, "reason": v.drop_reason, "phase": str(v.phase)}
                    for v in vehicles if v.dropped is not None},
        # packets dropped per vehicle (pinning, signing), non-finite reports, garbage per link
        "security": {v.id: {**v.link.telemetry.security.to_dict(),
                            "invalid_estimates": v.link.telemetry.invalid_estimates,
                            "link_garbage_datagrams": v.link.endpoint.garbage_datagrams}
                     for v in vehicles if v.link is not None},
        # loss, reordering, duplicates, latency and jitter per vehicle at the end
        "link_quality": {v.id: v.link.telemetry.quality.report()
                         for v in vehicles if v.link is not None},
    }


def _judged_window(recorder: FlightRecorder, options: FlightOptions,
                   vehicles: Sequence[VehicleStatus], t0: float, horizon: float,
                   pauses: Sequence[Sequence[float | None]], now: float) -> tuple[float, float]:
    """(end, t1) on the GCS clock: the end of the hold at the goals (pauses and the settling
    included), and the end of the judged flight: that end, the first fault or `now`."""
    paused = 0.0
    for a, b in pauses:
        assert a is not None
        paused += (now if b is None else b) - a
    end = t0 + horizon + options.hold_at_goal + recorder.goal_settle_s + paused
    first_fault = min((v.fault_time for v in vehicles if v.fault_time is not None),
                      default=math.inf)
    return end, min(end, first_fault, now)


def _tracking_errors(recorder: FlightRecorder, plan: Plan, vehicles: Sequence[VehicleStatus],
                     t0: float, pauses: Sequence[Sequence[float | None]], until: float,
                     planned: Callable[[str, np.ndarray], np.ndarray] | None,
                     off_plan: Mapping[str, float]
                     ) -> tuple[list[float], list[np.ndarray], list[np.ndarray]]:
    """(largest tracking error of each vehicle with reports in its judged window, every
    vehicle's report times, its positions): a vehicle is judged against where it was meant
    to be up to `until`, its fault or the moment it flew off the plans."""
    tracking = []
    times, positions = [], []
    for v in vehicles:
        rec = recorder.vehicles[v.id]
        t, p = rec.telemetry_arrays()
        stop = min(until, v.fault_time if v.fault_time is not None else math.inf)
        if v.id in off_plan:
            stop = min(stop, gcs_time(off_plan[v.id], t0, pauses))
        window = (t >= t0) & (t <= stop)
        if np.any(window):
            tau = plan_times(t[window], t0, pauses)
            meant = (plan.vehicles[v.index].sample(plan.scenario.dt, tau).position
                     if planned is None else planned(v.id, tau))
            tracking.append(float(np.max(np.linalg.norm(p[window] - meant, axis=1))))
        times.append(t)
        positions.append(p)
    return tracking, times, positions


def _separation_verdict(out: dict[str, Any], scenario: Scenario, options: FlightOptions,
                        times: list[np.ndarray], positions: list[np.ndarray], t0: float,
                        t_end: float) -> bool:
    """Fills the measured separation and whether it held into `out` (with its `why` line);
    returns whether it is unknown although several vehicles flew."""
    why: list[str] = out["why"]
    scale = np.asarray(scenario.separation_scale, dtype=float)
    separation, _ = measured_min_separation(times, positions, t0, t_end,
                                            options.rate_hz, scale,
                                            stale_after=STALE_REPORT_S)
    out["min_separation_measured"] = finite_or_none(separation)
    required = out["min_separation_required"]
    # judged as the planner verifies a plan: within its one SEPARATION_TOLERANCE
    unknown = len(times) > 1 and out["min_separation_measured"] is None
    if out["min_separation_measured"] is not None:
        out["separation_held"] = bool(separation >= required - SEPARATION_TOLERANCE)
        if not out["separation_held"]:
            why.append(f"vehicles came {separation:.4f} m apart, closer than the "
                       f"{required:.4f} m they must keep")
    elif unknown:
        why.append("separation unknown: too few or non-finite position reports to measure "
                   "how close the vehicles came")
    return unknown


def _stream_figures(out: dict[str, Any], recorder: FlightRecorder,
                    vehicles: Sequence[VehicleStatus], lateness: Sequence[float], t0: float,
                    t1: float) -> None:
    """Fills the setpoint rate over [t0, t1] and the stream's jitter into `out`."""
    counts = [sum(1 for s in recorder.vehicles[v.id].sp_t if t0 <= s <= t1)
              for v in vehicles]
    if t1 > t0 and counts:
        out["setpoint_rate_hz"] = float(np.mean(counts)) / (t1 - t0)
    stats = jitter_stats(lateness)
    out["jitter_p50_ms"] = finite_or_none(stats["jitter_p50_ms"])
    out["jitter_p99_ms"] = finite_or_none(stats["jitter_p99_ms"])


def _verdict(out: dict[str, Any], scenario: Scenario, options: FlightOptions,
             vehicles: Sequence[VehicleStatus], error: BaseException | None,
             unknown: bool) -> None:
    """Fills the largest goal error and whether the flight completed into `out`, and every
    reason why not (or, first, the line saying it did) into its `why`: the goals, faults,
    drops and landings judged once the separation is."""
    why: list[str] = out["why"]
    tolerances: dict[str, float] = out["goal_tolerances"]
    judged = [v for v in vehicles if v.dropped is None]
    goal_errors = [v.goal_error for v in judged if not math.isnan(v.goal_error)]
    if goal_errors:
        out["goal_error_max"] = max(goal_errors)
    # a faulty vehicle the others were replanned around lands on its own (its link may be
    # gone): named, not waited for; every other one must be down
    must_land = [v for v in vehicles if not (v.dropped is not None and v.fault is not None)]
    landed_ok = options.at_end != "land" or all(v.phase == VehiclePhase.LANDED
                                                for v in must_land)
    blocking = {v.id: v.fault for v in judged if v.fault is not None}
    # With a stated margin the clearance is a promise: breaking it is a failure. Without
    # one (margin 0), the plan's R is only reported against (the mock flies a few cm inside).
    promised = scenario.separation_margin > 0
    out["completed"] = bool(
        judged and error is None and not blocking and len(goal_errors) == len(judged)
        and all(v.goal_error <= tolerances[v.id] for v in judged) and landed_ok
        and not (promised and (out["separation_held"] is False or unknown)))
    why += [f"{vid}: fault {kind}" for vid, kind in blocking.items()]
    why += [f"{v.id}: fault {v.fault}, landed on its own motion; the others were replanned "
            f"around it" for v in vehicles if v.dropped is not None and v.fault is not None]
    why += [f"{v.id}: dropped ({v.dropped}) by a replan ({v.drop_reason}), not judged "
            f"against a goal" for v in vehicles if v.dropped is not None and v.fault is None]
    why += [f"{v.id}: {v.goal_error:.2f} m from its goal (tolerance {tolerances[v.id]:.2f} m)"
            for v in judged
            if not math.isnan(v.goal_error) and v.goal_error > tolerances[v.id]]
    if not vehicles:
        why.append("no vehicle flew")
    elif not judged:
        why.append("every vehicle was dropped")
    if error is None and not blocking and len(goal_errors) < len(judged):
        why.append("not every vehicle's goal error was measured")
    why += [f"{v.id}: landed and disarmed when last heard, then out of reach (link lost)"
            if v.phase == VehiclePhase.LANDED_LINK_LOST
            else f"{v.id}: not confirmed landed and disarmed ({v.phase})"
            for v in must_land if options.at_end == "land"
            and v.phase != VehiclePhase.LANDED]
    if out["completed"]:
        named = ("every vehicle" if len(judged) == len(vehicles)
                 else f"every vehicle flying to a goal ({len(judged)} of {len(vehicles)})")
        why.insert(0, f"complete: {named} within {max(tolerances.values()):.2f} m of "
                      f"its goal"
                      + (", landed and disarmed" if options.at_end == "land" else ", holding")
                      + ("; separation unknown" if unknown else ""))
