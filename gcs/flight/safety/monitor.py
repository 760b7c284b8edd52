"""Fault detection during a flight: per-vehicle checks and the fleet's live separation.

`FleetMonitor.check` runs every `PERIOD` (20 Hz) while a flight is under way. Per vehicle that
is meant to be in OFFBOARD, in this order (the first failing check flags it):

1. ``link_lost``: no message at all for `link_timeout` (1.5 s);
2. ``estimate_invalid``: a NaN or infinite position or velocity from the pinned peer within
   `link_timeout` (the link never stores it: `Telemetry.invalid_estimate_time`): a lost
   estimate, handled by the policy like any fault;
3. ``rebooted``: the vehicle's `time_boot_ms` went back (`Telemetry.reboot_time`): its
   autopilot restarted, whatever mode it came back in;
4. ``heartbeat_lost``: HEARTBEAT older than `heartbeat_timeout` (5 s: mode and armed state
   unknown);
5. ``geofence_breach``: the vehicle reports its geofence breached (SYS_STATUS's geofence
   bit unhealthy, or a STATUSTEXT naming it; PX4's GF_ACTION then switches it to Hold);
6. ``left_offboard``: HEARTBEAT shows another mode;
7. ``tracking_error``: farther than `tracking_error_max` from the plan at the flight time
   (written so that a NaN distance never passes).

Then the live minimum separation over every vehicle in the air (the plan's metric; an unheard
vehicle counts at its predicted position, and the alarm names it as predicted), with an
alarm below the clearance the vehicles must keep minus the alarm band
(`gcs.flight.safety.margin.separation_alarm_at`). The monitor only detects: what to do is the
flight's: the monitor tells what it finds to the flight it watches (`Watched`, the flight's
fault routing: `gcs.flight.run.faults`).

Packets with a vehicle's system id that its link dropped (another address, another
component, bad signatures: `SecurityCounters`) are told as they happen (a `dropped_packets`
event, at most once per `DROPS_NOTE_S` per vehicle, with their rate over the time since the
last report),
not only in the record: someone else is talking to the fleet.

Each link's quality is judged once a second (`gcs.flight.link.quality.LinkWatch`): a link
that degrades (loss, latency or jitter over its bounds) is told with its figures
(a `link_degraded` event), and again when it recovers (`link_recovered`); not a fault.

The station's own stalls (`gcs.flight.link.station`) are not a vehicle's fault: the monitor notes
each of its wake-ups later than `STALL_NOTE_S`; the link and heartbeat gaps count in
station-running time (the gap minus the station's stalls in it); after a late wake-up the
position checks wait one pass, so that the sockets have been read before positions are
judged (never two passes in a row, so a constantly busy station still judges); and a
vehicle may trail the plan by the stall time that ended within `CATCH_UP_S` (it got no
setpoints meanwhile).
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from gcs import frames
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.interface import Link
from gcs.flight.link.quality import WINDOW_S as LINK_WINDOW_S
from gcs.flight.link.quality import LinkWatch
from gcs.flight.link.signing import REPEATED_TIMESTAMPS
from gcs.flight.link.station import STALL_NOTE_S, StationStalls
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus, address_text
from gcs.flight.safety.margin import separation_alarm_at
from gcs.phases import AIRBORNE, EventKind, VehiclePhase
from planner import Plan

__all__ = ["CATCH_UP_S", "PERIOD", "FleetMonitor", "Watched", "drops_text", "vehicle_fault"]

#: Seconds between two checks.
PERIOD = 0.05
#: A vehicle unheard this long (s) is told (`Watched.on_silent`) before it is declared lost at
#: `link_timeout`, and the flight holds near the plan where the others keep the most room
#: from its predicted motion (`gcs.flight.safety.silence`). The sooner, the more room there
#: is: a lost vehicle flies on on its last setpoint while the others still follow the plan
#: (paper-circle8 blackholed mid-crossing, R = 1 m: 0.96 m after 0.8 s, 0.985 m after 0.5 s).
#: Well above the gaps of a jittery link (0.3 s).
SILENT_HOLD_S = 0.5
#: For this long after a station stall ends, a vehicle may trail the plan by the stall's
#: duration (it held its last setpoint meanwhile, then catches up).
CATCH_UP_S = 3.0
_TRACKED = (VehiclePhase.FLYING, VehiclePhase.HOLDING)

class Watched(Protocol):
    """The flight a `FleetMonitor` watches: where its vehicles are meant to be, and what it
    does with what the monitor finds (the flight's fault routing:
    `gcs.flight.run.faults.FaultRouter`). Every member must be given: a flight that forgot
    one must not fall back on a silent default."""

    def flight_time(self) -> float | None:
        """Seconds on the shared flight clock (None before it started: nothing is tracked)."""
        ...

    def planned(self, v: VehicleStatus, times: Sequence[float] | np.ndarray) -> np.ndarray | None:
        """`v`'s planned world positions at flight `times`, (T, 3), replans included; None:
        the monitor's plan."""
        ...

    def predicted(self, v: VehicleStatus, t: float) -> np.ndarray | None:
        """Where `v`, off the plans, is predicted at flight time `t` (None when not known):
        it stands in for its position once its reports are older than `link_timeout` (a
        faulty vehicle landing on its own)."""
        ...

    def on_fault(self, v: VehicleStatus, kind: str, detail: str) -> None:
        """`v` is faulty (`vehicle_fault`'s kinds, or ``tracking_error``)."""
        ...

    def on_separation(self, closest: float, alarm: float, between: str) -> None:
        """Two vehicles are `closest` m apart (the plan's metric), below `alarm` m; `between`
        names them (`FleetMonitor.closest_text`)."""
        ...

    def on_silent(self, v: VehicleStatus, silent: float) -> None:
        """`v`, meant to follow setpoints, has been unheard for `silent` s
        (> `SILENT_HOLD_S`); told once until it is heard again."""
        ...

    def on_heard(self, v: VehicleStatus) -> None:
        """`v`, told silent, is heard again."""
        ...


def vehicle_fault(link: Link, options: FlightOptions, now: float,
                  stalls: StationStalls | None = None) -> tuple[str, str] | None:
    """The first link/heartbeat/mode fault of a vehicle meant to be in OFFBOARD, as
    (kind, detail), or None; gaps count in station-running time when `stalls` is given."""
    tel = link.telemetry
    stalls = stalls if stalls is not None else StationStalls()
    silent = stalls.age(tel.message_time, now)
    age = stalls.age(tel.heartbeat_time, now)
    if silent > options.link_timeout:
        return "link_lost", f"no message for {silent:.2f} s"
    if (tel.invalid_estimate_time is not None
            and now - tel.invalid_estimate_time <= options.link_timeout):
        return "estimate_invalid", f"{tel.invalid_estimates} non-finite LOCAL_POSITION_NED"
    if tel.reboot_time is not None:  # before the mode: a restarted PX4 is out of OFFBOARD
        name = tel.mode.name if tel.mode is not None else "?"
        return "rebooted", (f"its clock (time_boot_ms) went back to {(tel.boot_ms or 0) / 1e3:.1f}"
                            f" s: the autopilot restarted; mode {name}, "
                            f"{'armed' if tel.armed else 'disarmed'}")
    if age > options.heartbeat_timeout:
        return "heartbeat_lost", f"no HEARTBEAT for {age:.2f} s"
    if tel.geofence_breach is not None:  # before the mode: PX4's GF_ACTION switches it
        name = tel.mode.name if tel.mode is not None else "?"
        return "geofence_breach", f"{tel.geofence_breach}, mode {name}"
    kind = tel.flown_by
    if tel.mode != kind.follow_mode:
        name = tel.mode.name if tel.mode is not None else "?"
        return "left_offboard", f"mode is now {name}{_warnings_text(tel.warnings, kind.title)}"
    return None


#: How many of PX4's latest warnings a fault's detail quotes.
WARNINGS_QUOTED = 3


def _warnings_text(warnings: Sequence[str], title: str) -> str:
    """"; PX4 warned: 'Preflight Fail: No valid data from Baro 0', 'Failsafe activated'"
    (`title` names the autopilot): why it took a vehicle out of the mode that follows
    setpoints is in its warnings since arming (a failsafe names the stale sensor or the lost
    link), or "" without any."""
    latest = list(warnings)[-WARNINGS_QUOTED:]
    return f"; {title} warned: " + ", ".join(repr(w) for w in latest) if latest else ""


#: A vehicle's newly dropped packets are told at most this often (s).
DROPS_NOTE_S = 5.0

def drops_text(delta: dict[str, int], latest: tuple[object, int] | None,
               window: float = 0.0) -> str:
    """"40 more packets dropped in 5.0 s, 8.0/s (40 unsigned), the latest from
    127.0.0.1:5555 (component 1)": the rate over `window` s (left out when 0) is the health
    signal, hostile traffic arriving as the vehicle's. Replays alone say where they come
    from (`REPEATED_TIMESTAMPS`)."""
    dropped = [reason for reason, n in delta.items() if n]
    reasons = ", ".join(f"{delta[reason]} {reason}" for reason in dropped)
    total = sum(delta.values())
    over = f" in {window:.1f} s, {total / window:.1f}/s" if window > 0.0 else ""
    where = ""
    if latest is not None:
        address, component = latest
        where = f", the latest from {address_text(address)} (component {component})"
    if dropped == ["replayed"]:
        where += f": {REPEATED_TIMESTAMPS}"
    return f"{total} more packets dropped{over} ({reasons}){where}"


class FleetMonitor:
    """Checks every vehicle of a flight and the fleet's separation (see the module)."""

    def __init__(self, vehicles: Sequence[VehicleStatus], plan: Plan, context: FlightContext,
                 watched: Watched) -> None:
        self.vehicles = vehicles
        self.plan = plan
        self.options: FlightOptions = context.options
        self.emit = context.emit
        """Tells the dropped packets and the links' quality as events."""
        self.watched = watched
        """The flight watched: what it plans and predicts, and what it does with a finding."""
        self.silent: set[str] = set()
        """The vehicles told silent and not heard since."""
        self._link_watch = LinkWatch(
            lambda vid, text: self.emit(vid, EventKind.LINK_DEGRADED, text),
            lambda vid, text: self.emit(vid, EventKind.LINK_RECOVERED, text))
        """Each link's quality judged once a second (`gcs.flight.link.quality`)."""
        self._drops_told: dict[str, tuple[dict[str, int], float]] = {}
        """Per vehicle: the counters last told and when."""
        self._drops_since: float | None = None
        """When the drops were first looked at (the first report's window starts there)."""
        self.min_separation = math.inf
        """Smallest separation seen so far (the plan's metric, m)."""
        self.closest_pair: tuple[str, str] | None = None
        """The two vehicles closest at the last check."""
        self.predicted_ids: set[str] = set()
        """The vehicles whose position at the last check was predicted, not reported (they
        are unheard: `Watched.predicted`)."""
        self.stalls = context.stalls
        """The station's own stalls, which this monitor's late wake-ups add to."""
        self._scale = np.asarray(plan.scenario.separation_scale, dtype=float)

    async def run(self, stopped: Callable[[], bool]) -> None:
        """Check every `PERIOD` until `stopped()`, noting the station's stalls."""
        waited = False
        while True:
            due = time.monotonic() + PERIOD
            await asyncio.sleep(PERIOD)
            if stopped():
                return
            woke = time.monotonic()
            late = woke - due > STALL_NOTE_S
            if late:
                self.stalls.note(due, woke)
            # positions read before the stall are stale: judge them once the sockets were read
            wait = late and not waited
            self.check(woke, positions=not wait)
            waited = wait

    def positions(self, now: float, t_flight: float | None = None) -> dict[str, np.ndarray]:
        """Every vehicle's world position at `now`, extrapolated from its last report (or,
        unheard, predicted at flight time `t_flight`, the watched flight's by default)."""
        out = {}
        self.predicted_ids = set()
        if t_flight is None:
            t_flight = self.watched.flight_time()
        for v in self.vehicles:
            if v.link is None or v.home is None:
                continue
            tel = v.link.telemetry
            if (t_flight is not None and tel.position_time is not None
                    and self.stalls.age(tel.position_time, now) > self.options.link_timeout):
                guess = self.watched.predicted(v, t_flight)
                if guess is not None:
                    out[v.id] = guess
                    self.predicted_ids.add(v.id)
                    continue
            if tel.position_ned is not None and tel.position_time is not None:
                p = np.asarray(tel.position_ned) + np.asarray(tel.velocity_ned) * (
                    now - tel.position_time)
                out[v.id] = frames.ned_to_world(p, v.home)
        return out

    def check(self, now: float, *, positions: bool = True) -> None:
        """One pass: flag faulty vehicles, update the separation, raise its alarm; with
        `positions` false only the link, heartbeat and mode checks run."""
        opts = self.options
        t_flight = self.watched.flight_time()
        where = self.positions(now, t_flight) if positions else {}
        trail = self.stalls.ended_since(now - CATCH_UP_S)
        for v in self.vehicles:
            if v.link is None or not v.expect_offboard or v.fault is not None:
                self.silent.discard(v.id)  # a faulty vehicle is its fault's business now
                continue
            self._silence(v, now)
            fault = vehicle_fault(v.link, opts, now, self.stalls)
            if fault is not None:
                self.watched.on_fault(v, *fault)
            elif t_flight is not None and v.phase in _TRACKED and v.id in where:
                v.tracking_error = self._tracking_error(v, where[v.id], t_flight, trail)
                if not v.tracking_error <= opts.tracking_error_max:  # NaN never passes
                    self.watched.on_fault(v, "tracking_error",
                                          f"{v.tracking_error:.2f} m from the plan "
                                          f"(bound {opts.tracking_error_max:g} m)")
        if positions:
            self.check_separation(where)
        self.report_drops(now)
        self._link_watch.check({v.id: v.link.telemetry.quality for v in self.vehicles
                                if v.link is not None}, now,
                               self.stalls.ended_since(now - LINK_WINDOW_S) > 0.0)

    def report_drops(self, now: float) -> None:
        """Tell each vehicle's packets dropped since last told (at most every DROPS_NOTE_S)."""
        if self._drops_since is None:
            self._drops_since = now
        for v in self.vehicles:
            if v.link is None:
                continue
            security = v.link.telemetry.security
            told, when = self._drops_told.get(v.id, ({}, -math.inf))
            if now - when < DROPS_NOTE_S or security.total == sum(told.values()):
                continue
            counts = security.to_dict()
            delta = {k: n - told.get(k, 0) for k, n in counts.items()}
            latest = max(((k, a) for k, a in v.link.dropped_from.items()
                          if delta.get(k)), default=None, key=lambda item: delta[item[0]])
            self._drops_told[v.id] = (counts, now)
            window = now - (when if math.isfinite(when) else self._drops_since)
            self.emit(v.id, EventKind.DROPPED_PACKETS,
                      drops_text(delta, None if latest is None else latest[1], window))

    def _silence(self, v: VehicleStatus, now: float) -> None:
        """Tell a vehicle falling silent, and heard again."""
        assert v.link is not None
        silent = self.stalls.age(v.link.telemetry.message_time, now)
        if silent > SILENT_HOLD_S and v.id not in self.silent:
            self.silent.add(v.id)
            self.watched.on_silent(v, silent)
        elif silent <= SILENT_HOLD_S and v.id in self.silent:
            self.silent.discard(v.id)
            self.watched.on_heard(v)

    def closest_text(self) -> str:
        """"uav2 (predicted: unheard) and uav3": the pair closest at the last check."""
        if self.closest_pair is None:
            return ""
        return " and ".join(f"{vid} (predicted: unheard)" if vid in self.predicted_ids
                            else vid for vid in self.closest_pair)

    def _tracking_error(self, v: VehicleStatus, position: np.ndarray, t: float,
                        trail: float) -> float:
        """Distance to the plan at flight time `t`, or to the nearest plan point of the last
        `trail` s (the plan time the station lost to its own stalls)."""
        plan = self.plan
        times = [t] if trail <= 0 else np.linspace(max(0.0, t - trail), t, min(
            64, 2 + math.ceil(4 * trail / plan.scenario.dt)))
        planned = self.watched.planned(v, times)
        if planned is None:
            planned = plan.vehicles[v.index].sample(plan.scenario.dt, times).position
        return float(np.min(np.linalg.norm(planned - position, axis=1)))

    def check_separation(self, positions: dict[str, np.ndarray]) -> None:
        plan = self.plan
        opts = self.options
        # Every vehicle in the air counts, a faulty one going down among the others too.
        ids = [v.id for v in self.vehicles if v.id in positions and v.phase in AIRBORNE]
        if len(ids) >= 2:
            pts = np.stack([positions[vid] for vid in ids]) / self._scale
            i, j = np.triu_indices(len(pts), k=1)
            distances = np.linalg.norm(pts[i] - pts[j], axis=1)
            k = int(np.argmin(distances))
            closest = float(distances[k])
            self.closest_pair = (ids[i[k]], ids[j[k]])
            self.min_separation = min(self.min_separation, closest)
            alarm = separation_alarm_at(plan.scenario, opts.separation_alarm)
            if not closest >= alarm:  # a distance that is not a number alarms too
                self.watched.on_separation(closest, alarm, self.closest_text())
