"""The fleet executor: fly a plan on a fleet of PX4 vehicles with one shared mission clock.

`FlightExecutor(plan, fleet)` runs the whole flight on the caller's asyncio loop. It keeps the
shared-clock orchestration; the PX4 procedure of one vehicle is `gcs.flight.vehicle`, fault
detection `gcs.flight.monitor`, the record and its summary `gcs.flight.record`. A setpoint goes
executor -> `Streamer` (one tick for the whole fleet) -> `VehicleLink` -> UDP:

1. connect: open the fleet's links, send the GCS HEARTBEAT at 1 Hz, wait for every vehicle's
   HEARTBEAT and LOCAL_POSITION_NED (refuse a vehicle that is already armed or not PX4);
   place each vehicle's home in the world frame (fleet file, or `world_origin` and the
   vehicle's GPS_GLOBAL_ORIGIN / HOME_POSITION);
2. per vehicle, concurrently: stream setpoints holding its current position, then OFFBOARD
   (MAV_CMD_DO_SET_MODE, retried while TEMPORARILY_REJECTED), then arm (retried while
   TEMPORARILY_REJECTED, up to `arm_timeout`), each confirmed by COMMAND_ACK *and* HEARTBEAT;
   then climb vertically from home to the plan's start (then horizontally, if the home is not
   below the start);
3. when every vehicle is within `start_tolerance` of its start, start the shared mission
   clock: every vehicle's setpoint for tick k leaves in tick k (`gcs.flight.stream.Streamer`);
4. after the horizon, hold at the goals for `hold_at_goal`, measure the goal errors, then land
   (MAV_CMD_NAV_LAND) and wait for the auto-disarm, or switch to Hold (`at_end`).

Monitors (20 Hz, `gcs.flight.monitor`): no message at all for `link_timeout` (1.5 s: a lost
link), HEARTBEAT older than `heartbeat_timeout` (5 s: mode and armed state unknown), leaving
OFFBOARD, tracking error over `tracking_error_max`, and the live minimum separation. A flagged
vehicle triggers the policy: ``hold_all`` / ``land_all`` stop the mission (`MissionAborted`),
``land_faulty`` lands that vehicle and carries on (the mission then does not count as
completed).

Safety: nothing is armed before `run()`; every error path ends in `vehicle.secure`, which disarms
armed vehicles still on the ground, sends airborne ones to land (or Hold for an explicit hold
abort), stops their streams, and waits for landed vehicles to disarm. A vehicle that does not
answer still gets no more setpoints, so PX4's own offboard-loss failsafe lands it.

Python API (for the CLI and the REST API)::

    mission = FlightExecutor(plan, fleet_spec, options)
    task = mission.start()                 # or: record = await mission.run()
    mission.snapshot()                     # JSON-ready live state (positions in world frame)
    async for event in mission.events():   # every event until the mission ends
        ...
    await mission.abort("land")            # or "hold": all vehicles at once
    record = await task                    # the flight record (dict); also mission.record

`run()` returns the flight record when the mission ran to its end (check
``record["summary"]["completed"]``) and raises a `GcsError` (`ArmingRefused`, `MissionAborted`,
...) otherwise, after the vehicles were made safe; `mission.record` holds the record then too.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import AsyncIterator, Awaitable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from gcs import frames, px4
from gcs.errors import (
    MissionAborted,
    PlanRejected,
    PreflightFailed,
    StateConflict,
    VehicleTimeout,
)
from gcs.flight import vehicle
from gcs.flight.fleetfile import FleetSpec, FlightOptions
from gcs.flight.health import PreflightThresholds, health_report, preflight_problems
from gcs.flight.link import DECODED_IDS, LinkHub, VehicleLink
from gcs.flight.margin import check_margin
from gcs.flight.monitor import PERIOD, FleetMonitor
from gcs.flight.phases import EventKind
from gcs.flight.record import FlightRecorder, finite_or_none, goal_tolerance, summarise
from gcs.flight.setpoints import Setpoint, SetpointTrack, hold_track, plan_tracks, transfer_track
from gcs.flight.station import StallReport, StationStalls
from gcs.flight.stream import Streamer
from gcs.flight.vehicle import VehicleStatus
from gcs.tasks import TaskSet
from planner import Plan
from planner.verify import verify

__all__ = ["TRACKING_TOLERANCE_M", "FlightExecutor", "VehicleStatus"]

#: Documented bound on how much closer two vehicles may come in flight than the plan's R:
#: tracking error of each (centimetres on the mock) plus the skew between their position
#: reports. The end-to-end test checks the measured separation against R minus this.
TRACKING_TOLERANCE_M = 0.1


class FlightExecutor:
    """One flight of a plan on a fleet; see the module docstring."""

    def __init__(self, plan: Plan, fleet: FleetSpec, options: FlightOptions | None = None) -> None:
        # Checked again here on the trajectories themselves: a plan file's own verification
        # block is only a claim (it may have been edited, or written by another tool).
        if plan.status != "converged":
            raise PlanRejected(f"refusing to fly a plan with status {plan.status!r}: "
                               f"{plan.message}")
        check = verify(plan.scenario, plan.positions(), plan.velocities(),
                       plan.accelerations())
        if not check.verified:
            raise PlanRejected("refusing to fly a plan that fails verification: "
                               + "; ".join(check.failures()))
        self.plan = plan
        self.fleet = fleet
        self.options = options or fleet.options
        self.margin = check_margin(plan, fleet.position_error)
        if not self.margin.ok and self.options.margin_check == "refuse":
            raise PlanRejected(f"refusing to fly: {self.margin.message()}")
        specs = fleet.for_plan(plan.scenario.ids)
        self.vehicles = [VehicleStatus(spec, i) for i, spec in enumerate(specs)]
        self._by_id = {v.id: v for v in self.vehicles}
        self.recorder = FlightRecorder([s.id for s in specs], [s.system_id for s in specs])
        self.phase = "created"
        self.record: dict[str, Any] | None = None
        self.mission_start: float | None = None
        """GCS-clock time (s) of mission time 0."""
        self.stalls = StationStalls()
        """The station's own stalls (`gcs.flight.station`), not counted against vehicles."""
        self.stalls.listeners.append(self._on_stall)
        self._stall_report = StallReport()
        self.monitor = FleetMonitor(self.vehicles, plan, self.options,
                                    flight_time=self.mission_time, on_fault=self._on_fault,
                                    on_separation=self._on_separation, stalls=self.stalls)
        self.streamer: Streamer | None = None
        self._t0 = time.monotonic()
        self._hub: LinkHub | None = None
        self._tracks: list[SetpointTrack] = []
        self._mission_tick = 0
        """Streamer tick of mission time 0, moved on by every pause."""
        self._flow: asyncio.Task[None] | None = None
        self._abort: tuple[str, str] | None = None
        self._secure_task: asyncio.Task[None] | None = None
        self._subscribers: list[asyncio.Queue[dict[str, Any] | None]] = []
        self._background = TaskSet()
        self._task: asyncio.Task[dict[str, Any]] | None = None
        self._yaw_ned = frames.world_yaw_to_ned(self.options.yaw)
        self.pauses: list[list[float | None]] = []
        """[start, end] of every pause (GCS clock, s; end None while paused)."""
        self._paused_total = 0.0
        self._pause: _Pause | None = None

    # ================================================================ public API

    def now(self) -> float:
        """Seconds on the GCS clock (0 when the mission object was made or started)."""
        return time.monotonic() - self._t0

    def mission_time(self) -> float | None:
        """Seconds on the shared mission clock (None before it started); it stops while
        paused."""
        if self.mission_start is None:
            return None
        if self._pause is not None:
            return self._pause.plan_tick / self._streamer().rate
        return self.now() - self.mission_start - self._paused_total

    @property
    def paused(self) -> bool:
        return self._pause is not None

    def pause(self) -> float:
        """Stop the shared mission clock: from the next tick every vehicle flying the plan
        holds the plan's setpoint of that same plan time (at rest), so the fleet stays as
        separated as the plan is at that instant. Returns the plan time it holds.
        `StateConflict` unless the plan is being flown (and not already paused). After
        `pause_limit` s the `pause_expiry` action (land or hold) ends the mission."""
        if self._pause is not None:
            raise StateConflict("status", "already paused")
        if self.phase != "flying" or self._abort is not None or self.mission_start is None:
            raise StateConflict("status", f"only a flying mission can be paused (phase "
                                          f"{self.phase})")
        streamer = self._streamer()
        tick = streamer.next_tick()
        plan_tick = tick - self._mission_tick
        held = []
        for v, track in zip(self.vehicles, self._tracks, strict=True):
            assignment = streamer.assignments.get(v.id)
            if assignment is None or assignment.track is not track:
                continue  # landing (land_faulty) or already stopped: not ours to hold
            sp = track.at(plan_tick)
            streamer.assign(v.id, assignment.link, hold_track(sp.position, sp.yaw,
                                                              streamer.rate), tick)
            held.append(v.id)
        started = streamer.tick_time(tick) - self._t0
        self._pause = _Pause(tick, plan_tick, held, asyncio.ensure_future(self._pause_limit()))
        self.pauses.append([started, None])
        self.phase = "paused"
        t = plan_tick / streamer.rate
        self._emit(None, "pause", f"mission clock stopped at t={t:.2f} s; "
                                  f"{', '.join(held)} holding (limit "
                                  f"{self.options.pause_limit:g} s, then "
                                  f"{self.options.pause_expiry})")
        return t

    def resume(self) -> float:
        """Restart the shared mission clock where `pause` stopped it; returns that plan time.
        `StateConflict` unless paused."""
        pause = self._pause
        if pause is None or self._abort is not None:
            raise StateConflict("status", f"not paused (phase {self.phase})")
        streamer = self._streamer()
        tick = streamer.next_tick()
        for v, track in zip(self.vehicles, self._tracks, strict=True):
            if v.id in pause.held and v.id in streamer.assignments and v.fault is None:
                streamer.assign(v.id, streamer.assignments[v.id].link, track,
                                tick - pause.plan_tick)
        self._paused_total += (tick - pause.tick) / streamer.rate
        self._mission_tick += tick - pause.tick
        self.pauses[-1][1] = streamer.tick_time(tick) - self._t0
        pause.limit.cancel()
        self._pause = None
        self.phase = "flying"
        t = pause.plan_tick / streamer.rate
        self._emit(None, "resume", f"mission clock running again from t={t:.2f} s after "
                                   f"{(tick - pause.tick) / streamer.rate:.1f} s")
        return t

    async def _pause_limit(self) -> None:
        await asyncio.sleep(self.options.pause_limit)
        action = self.options.pause_expiry
        self._emit(None, "pause_limit", f"paused for {self.options.pause_limit:g} s: "
                                        f"{action} all")
        await self.abort(action, f"paused longer than {self.options.pause_limit:g} s")

    def start(self) -> asyncio.Task[dict[str, Any]]:
        """Run the mission in a background task (on the running loop) and return the task."""
        if self._task is None:
            self._task = asyncio.create_task(self.run(), name="mission")
        return self._task

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        """Stop the mission now: every vehicle to land or to Hold (PX4 AUTO.LOITER) at once.

        Returns once the commands were sent and answered (or timed out); `run()` then raises
        `MissionAborted` after waiting for landed vehicles to disarm.
        """
        if action not in ("land", "hold"):
            raise ValueError("action must be 'land' or 'hold'")
        if self._abort is None:
            self._abort = (action, reason)
            self._end_pause()
            self._emit(None, "abort", f"{reason}: {action} all")
            if self._flow is not None and not self._flow.done():
                self._flow.cancel()
        await self._secure_all(self._abort[0])

    def snapshot(self) -> dict[str, Any]:
        """JSON-ready live state: phase, mission time, per vehicle position (world frame),
        mode, armed, heartbeat age, tracking error, fault; live minimum separation."""
        now = time.monotonic()
        vehicles = []
        for v in self.vehicles:
            tel = v.link.telemetry if v.link is not None else None
            position = None
            velocity = None
            if tel is not None and tel.position_ned is not None and v.home is not None:
                position = frames.ned_to_world(tel.position_ned, v.home).tolist()
                velocity = frames.ned_vector_to_world(tel.velocity_ned).tolist()
            age = v.link.heartbeat_age(now) if v.link is not None else math.inf
            silent = v.link.link_age(now) if v.link is not None else math.inf
            vehicles.append({
                "id": v.id, "system_id": v.spec.system_id, "phase": v.phase,
                "fault": v.fault,
                "mode": tel.mode.name if tel is not None and tel.mode is not None else None,
                "armed": bool(tel.armed) if tel is not None else False,
                "heartbeat_age": None if math.isinf(age) else round(age, 3),
                "link_age": None if math.isinf(silent) else round(silent, 3),
                "position": position, "velocity": velocity,
                "tracking_error": finite_or_none(v.tracking_error),
                **(health_report(tel) if tel is not None else {}),
            })
        return {
            "phase": self.phase,
            "mission_time": self.mission_time(),
            "horizon": self.plan.scenario.horizon,
            "min_separation_live": finite_or_none(self.monitor.min_separation),
            "vehicles": vehicles,
            "events": len(self.recorder.events),
        }

    async def events(self) -> AsyncIterator[dict[str, Any]]:
        """Every event from now until the mission ends ({"t", "vehicle", "kind", "detail"})."""
        queue: asyncio.Queue[dict[str, Any] | None] = asyncio.Queue()
        self._subscribers.append(queue)
        try:
            while True:
                event = await queue.get()
                if event is None:
                    return
                yield event
        finally:
            self._subscribers.remove(queue)

    async def run(self) -> dict[str, Any]:
        """Fly the mission; returns the flight record or raises a `GcsError` (see module)."""
        self._t0 = time.monotonic()
        error: BaseException | None = None
        if self.margin.needed is not None or self.margin.planned > 0:
            self._emit(None, "margin" if self.margin.ok else "margin_warning",
                       self.margin.message())
        self.streamer = Streamer(self.options.rate_hz, boot_epoch=self._t0,
                                 realtime=self.options.stream_priority == "realtime")
        self.streamer.listeners.append(self._on_send)
        self.streamer.stall_listeners.append(self.stalls.note)
        monitor: asyncio.Task[None] | None = None
        try:
            async with LinkHub(decode_ids=DECODED_IDS) as hub:
                self._hub = hub
                try:
                    await self._open_links(hub)
                    if self._abort is not None:  # aborted while the links were opening
                        raise MissionAborted(self._abort[1])
                    self.streamer.start()
                    if self.streamer.realtime:
                        await asyncio.sleep(0)  # its first step sets the priority
                        self._emit(None, "stream_priority", self.streamer.scheduling)
                    monitor = asyncio.create_task(
                        self.monitor.run(lambda: self._abort is not None), name="mission-monitor")
                    self._flow = asyncio.create_task(self._fly(), name="mission-flow")
                    try:
                        await self._flow
                    except asyncio.CancelledError:
                        if self._abort is None or _cancelling():
                            raise
                        raise MissionAborted(self._abort[1]) from None
                except BaseException as exc:
                    error = exc
                    self.phase = "aborted" if isinstance(exc, MissionAborted) else "failed"
                    self._emit(None, "error", f"{type(exc).__name__}: {exc}")
                    await asyncio.shield(self._make_safe())
                    raise
                finally:
                    if monitor is not None:
                        monitor.cancel()
                        with contextlib.suppress(asyncio.CancelledError):
                            await monitor
                    await self.streamer.stop()
        finally:
            self._finish_record(error)
            for queue in self._subscribers:
                queue.put_nowait(None)
        assert self.record is not None
        return self.record

    # ================================================================ the flight

    async def _open_links(self, hub: LinkHub) -> None:
        for v in self.vehicles:
            # issue 8 (link security): the fleet file's signing key and pinned peer.
            v.link = await hub.add(v.id, v.spec.connection, v.spec.system_id,
                                   v.spec.component_id, signing_key=v.spec.signing_key,
                                   peer=v.spec.peer)
            v.link.listeners.append(self._on_message)
            if v.spec.home is not None:
                v.home = np.asarray(v.spec.home, dtype=float)
                self.recorder.vehicles[v.id].home = v.home.tolist()

    async def _fly(self) -> None:
        opts = self.options
        self.phase = "connecting"
        await _all(self._connect(v) for v in self.vehicles)
        self._tracks = plan_tracks(self.plan, [v.home for v in self.vehicles], opts.rate_hz,
                                   opts.yaw, extra_s=opts.hold_at_goal)
        scenario = self.plan.scenario
        goals = scenario.assigned_goals  # under free assignment, the goal each was given
        for v in self.vehicles:
            v.start_ned = frames.world_to_ned(scenario.starts[v.index], v.home)
            v.goal_ned = frames.world_to_ned(goals[v.index], v.home)
        self.phase = "preparing"
        await _all(self._prepare(v) for v in self.vehicles)
        self.phase = "gathering"
        await self._gather()
        self.phase = "flying"
        await self._fly_plan()
        self.phase = "finishing"
        await self._finish()
        self.phase = "finished"

    async def _connect(self, v: VehicleStatus) -> None:
        link = v.linked
        await vehicle.connect(link, v.spec, self.options.connect_timeout, self.stalls)
        if v.home is None:
            assert self.fleet.world_origin is not None
            v.home, source = await vehicle.resolve_home(link, v.id, self.fleet.world_origin)
            self.recorder.vehicles[v.id].home = v.home.tolist()
            self._emit(v.id, "home", f"from {source}: {np.round(v.home, 3).tolist()}")
        await self._preflight(v)
        if self.options.message_rates == "request":
            answers = await vehicle.request_message_rates(
                link, vehicle.message_rates(self.options.position_rate_hz))
            self._emit(v.id, "message_rates", ", ".join(f"{k} {a}" for k, a in answers.items()))
        v.phase = "connected"
        mode = link.telemetry.mode
        self._emit(v.id, "connected", f"mode {mode.name if mode else '?'}, home "
                                      f"{np.round(v.home, 3).tolist()}")

    async def _preflight(self, v: VehicleStatus) -> None:
        """The pre-flight gate (`gcs.flight.health`): wait up to `preflight_wait` for the
        vehicle to be fit; then refuse it (`PreflightFailed`), or with `preflight: override`
        record what was overridden and carry on."""
        opts = self.options
        limits = PreflightThresholds(min_battery_pct=opts.min_battery_pct)
        link = v.linked
        if opts.preflight == "check":
            await link.wait_for(lambda t: not preflight_problems(t, limits), opts.preflight_wait)
        problems = preflight_problems(link.telemetry, limits)
        if not problems:
            return
        if opts.preflight == "check":
            raise PreflightFailed(v.id, problems)
        self._emit(v.id, "preflight_override", "; ".join(problems))

    async def _prepare(self, v: VehicleStatus) -> None:
        link = v.linked
        streamer = self._streamer()
        opts = self.options
        here = np.asarray(link.telemetry.position_ned, dtype=float)
        streamer.assign(v.id, link, hold_track(here, self._yaw_ned, opts.rate_hz))
        await asyncio.sleep(opts.prestream)
        v.phase = "arming"
        await vehicle.set_mode(link, px4.OFFBOARD, confirm_timeout=opts.heartbeat_timeout,
                               retry_for=vehicle.MODE_RETRY_FOR, stalls=self.stalls)
        self._emit(v.id, "mode", f"{px4.OFFBOARD.name} confirmed")
        v.expect_offboard = True

        def attempt() -> None:
            v.arm_sent = True

        def accepted() -> None:
            v.armed_by_us = True

        attempts = await vehicle.arm(link, timeout=opts.arm_timeout,
                                     confirm_timeout=opts.heartbeat_timeout,
                                     on_attempt=attempt, on_accepted=accepted,
                                     stalls=self.stalls)
        self._emit(v.id, "armed", f"after {attempts} attempt(s)")
        assert v.start_ned is not None
        track = transfer_track(here, v.start_ned, opts.climb_speed, self._yaw_ned, opts.rate_hz)
        streamer.assign(v.id, link, track)
        v.phase = "climbing"
        self._emit(v.id, "climb", f"to start, {track.duration:.1f} s")

    async def _gather(self) -> None:
        tol = self.options.start_tolerance
        clock = self.stalls.clock  # the station's own stalls do not use up the timeout
        deadline = clock() + self.options.gather_timeout
        streamer = self._streamer()
        while True:
            waiting = []
            for v in self.vehicles:
                assignment = streamer.assignments.get(v.id)
                done = (assignment is not None
                        and streamer.tick - assignment.start_tick >= len(assignment.track) - 1)
                error = v.distance_ned(v.start_ned)
                if done and error <= tol:
                    if v.phase != "at_start":
                        v.phase = "at_start"
                        self._emit(v.id, "at_start", f"{error:.3f} m from start")
                else:
                    waiting.append((v.id, error))
            if not waiting:
                return
            if clock() > deadline:
                vid, error = waiting[0]
                raise VehicleTimeout(vid, f"not within {tol:g} m of its start after "
                                          f"{self.options.gather_timeout:g} s "
                                          f"({error:.2f} m away)")
            await asyncio.sleep(PERIOD)

    async def _fly_plan(self) -> None:
        streamer = self._streamer()
        start_tick = streamer.next_tick() + 1
        for v, track in zip(self.vehicles, self._tracks, strict=True):
            streamer.assign(v.id, v.linked, track, start_tick)
            v.phase = "flying"
        self.mission_start = streamer.tick_time(start_tick) - self._t0
        self._mission_tick = start_tick
        streamer.measuring = True
        self._emit(None, "mission_start", f"tick {start_tick}, horizon "
                                          f"{self.plan.scenario.horizon:g} s")
        horizon = self.plan.scenario.horizon
        await self._sleep_until_mission_time(horizon)
        for v in self.vehicles:
            if v.phase == "flying":
                v.phase = "holding"
        self._emit(None, "horizon", "plan ended, holding at the goals")
        held = time.monotonic()
        await self._sleep_until_mission_time(horizon + self.options.hold_at_goal)
        # the hold lasts `hold_at_goal` of station-running time: a vehicle that got no
        # setpoints during a stall of the station is still catching up
        while (lost := self.stalls.overlap(held, time.monotonic())) > 0:
            held += lost
            await asyncio.sleep(lost)
        streamer.measuring = False
        for v in self.vehicles:
            if v.fault is None:
                v.goal_error = v.distance_ned(v.goal_ned)
                v.goal_tolerance = goal_tolerance(self.options, self.fleet.position_error,
                                                  v.linked.telemetry.gps_h_acc)
        self._emit(None, "goal_errors", ", ".join(
            f"{v.id} {v.goal_error:.3f} m" for v in self.vehicles if v.fault is None))

    async def _finish(self) -> None:
        live = [v for v in self.vehicles if v.fault is None]
        if self.options.at_end == "hold":
            await _all(self._hold(v) for v in live)
            for v in live:
                v.phase = "hovering"
        else:
            await _all(self._land(v) for v in live)
        # and the ones a land_faulty policy sent down
        await vehicle.wait_disarmed([v for v in self.vehicles if v.phase == "landing"],
                                    self.options, self._emit, self.stalls)

    # ================================================================ making safe

    def _land(self, v: VehicleStatus) -> Awaitable[None]:
        return vehicle.land_vehicle(v, self.options, self._emit, self._stop_stream,
                                    self.stalls)

    def _hold(self, v: VehicleStatus) -> Awaitable[None]:
        return vehicle.hold_vehicle(v, self.options, self._emit, self._stop_stream,
                                    self.stalls)

    def _stop_stream(self, vehicle_id: str) -> None:
        self._streamer().unassign(vehicle_id)

    async def _secure_all(self, action: str) -> None:
        if self._secure_task is None:
            # Freeze every stream where it is, so nothing moves on along the plan meanwhile.
            # (An abort can come before run() made the streamer: then nothing streams, and
            # `secure` skips the vehicles, none of which has a link yet.)
            streamer = self.streamer
            if streamer is not None:
                for vid, assignment in list(streamer.assignments.items()):
                    if assignment.last is not None:
                        streamer.assign(vid, assignment.link, hold_track(
                            assignment.last.position, assignment.last.yaw, streamer.rate))
            self._secure_task = asyncio.ensure_future(asyncio.gather(
                *(vehicle.secure(v, action, self.options, self._emit, self._stop_stream,
                                 self.stalls)
                  for v in self.vehicles),
                return_exceptions=True))
        await asyncio.shield(self._secure_task)

    async def _make_safe(self) -> None:
        """After an error or abort: secure everyone, wait for landed vehicles to disarm."""
        action = self._abort[0] if self._abort is not None else "land"
        await self._secure_all(action)
        if action == "land":
            await vehicle.wait_disarmed([v for v in self.vehicles if v.arm_sent], self.options,
                                        self._emit, self.stalls)
        for v in self.vehicles:
            if v.link is not None and v.link.telemetry.armed and v.phase != "hovering":
                self._emit(v.id, "still_armed", "still armed: operator attention required")

    # ================================================================ monitoring

    def _on_fault(self, v: VehicleStatus, kind: str, detail: str) -> None:
        v.fault = kind
        v.fault_time = self.now()
        v.phase = "faulty"
        policy = self.options.policy
        self._emit(v.id, "fault", f"{kind}: {detail} -> policy {policy}")
        if policy == "land_faulty":
            self._background.spawn(self._land(v))
        else:
            action = "hold" if policy == "hold_all" else "land"
            self._background.spawn(self.abort(action, f"{v.id} {kind} ({detail})"))

    def _on_separation(self, closest: float, alarm: float) -> None:
        if self._abort is not None:
            return
        # Two vehicles about to meet is nobody's single fault: stop everyone where they are
        # (PX4 Hold) rather than send anyone down through others.
        self._emit(None, "separation_alarm",
                   f"vehicles {closest:.2f} m apart (alarm below {alarm:.2f} m)")
        self._background.spawn(self.abort("hold", f"separation {closest:.2f} m"))

    # ================================================================ recording

    def _on_send(self, vehicle_id: str, tick: int, setpoint: Setpoint, sent: float) -> None:
        self.recorder.vehicles[vehicle_id].add_setpoint(round(sent - self._t0, 5), tick,
                                                        setpoint)

    def _on_message(self, link: VehicleLink, msg: Any, now: float) -> None:
        kind = msg.get_type()
        v = self._by_id[link.vehicle_id]
        rec = self.recorder.vehicles[v.id]
        t = round(now - self._t0, 5)
        if kind == "LOCAL_POSITION_NED" and v.home is not None:
            rec.tel_t.append(t)
            rec.tel_pos.append(frames.ned_to_world((msg.x, msg.y, msg.z), v.home).tolist())
            rec.tel_vel.append(frames.ned_vector_to_world((msg.vx, msg.vy, msg.vz)).tolist())
        elif kind == "HEARTBEAT" and msg.get_srcComponent() == link.component_id:
            tel = link.telemetry
            mode = tel.mode.name if tel.mode is not None else None
            if mode != v.last_mode or tel.armed != v.last_armed:
                v.last_mode, v.last_armed = mode, tel.armed
                rec.modes.append({"t": t, "mode": mode, "armed": tel.armed})
                self._emit(v.id, "mode_change", f"{mode}, {'armed' if tel.armed else 'disarmed'}")
        elif kind == "STATUSTEXT":  # the link has joined a chunked text: its latest is whole
            self._emit(v.id, "statustext", link.telemetry.statustexts[-1])

    def _on_stall(self, start: float, end: float) -> None:
        text = self._stall_report.add(start, end)
        if text is not None:
            self._emit(None, EventKind.STATION_STALL, text)

    def _emit(self, vehicle: str | None, kind: str, detail: str = "") -> None:
        event = self.recorder.event(self.now(), vehicle, kind, detail)
        for queue in self._subscribers:
            queue.put_nowait(event)

    def _finish_record(self, error: BaseException | None) -> None:
        self._end_pause()
        text = self._stall_report.flush(time.monotonic())
        if text is not None:
            self._emit(None, EventKind.STATION_STALL, text)
        scenario = self.plan.scenario
        self.recorder.meta = {
            "plan": scenario.to_dict(),
            "fleet": self.fleet.to_dict(),
            "options": self.options.to_dict(),
            "mission_start": self.mission_start,
            "pauses": self.pauses,
            "horizon": scenario.horizon,
            "error": None if error is None else {
                "type": type(error).__name__, "message": str(error) or type(error).__name__},
        }
        streamer = self.streamer
        self.recorder.summary = summarise(
            self.recorder, self.plan, self.options, self.vehicles,
            mission_start=self.mission_start, pauses=self.pauses, now=self.now(),
            margin=self.margin, position_error=self.fleet.position_error,
            missed_ticks=streamer.missed_ticks if streamer is not None else 0,
            lateness=streamer.lateness if streamer is not None else None, error=error)
        self.record = self.recorder.to_dict()

    # ================================================================ helpers

    def _streamer(self) -> Streamer:
        assert self.streamer is not None
        return self.streamer

    async def _sleep_until_mission_time(self, t: float) -> None:
        """Sleep until mission time `t`; a pause on the way makes it wait longer (the mission
        clock never runs faster than the GCS clock, so sleeping the remainder never
        oversleeps)."""
        while True:
            now = self.mission_time()
            assert now is not None
            if now >= t:
                return
            await asyncio.sleep(t - now)

    def _end_pause(self) -> None:
        """Forget a pause (the mission is ending); its interval ends now."""
        if self._pause is not None:
            self._pause.limit.cancel()
            self._pause = None
            if self.pauses and self.pauses[-1][1] is None:
                self.pauses[-1][1] = self.now()


@dataclass
class _Pause:
    """A pause under way."""

    tick: int
    """Streamer tick from which the fleet holds."""
    plan_tick: int
    """The plan's tick (mission time * rate) every vehicle holds."""
    held: list[str]
    limit: asyncio.Future[None]
    """The pause-limit timer."""


def _cancelling() -> bool:
    task = asyncio.current_task()
    return task is not None and task.cancelling() > 0


async def _all(coros: Iterable[Awaitable[Any]]) -> None:
    """Run concurrently; on the first error cancel the rest and raise that error."""
    tasks = [asyncio.ensure_future(c) for c in coros]
    if not tasks:  # nothing to run (no vehicle left): asyncio.wait refuses an empty set
        return
    try:
        done, _pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
        for task in done:
            if task.exception() is not None:
                raise task.exception()  # type: ignore[misc]
    finally:
        for task in tasks:
            if not task.done():
                task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
