"""The fleet executor: fly a plan on a fleet of PX4 vehicles with one shared mission clock.

`FlightExecutor(plan, fleet)` runs the whole flight on the caller's asyncio loop:

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

Monitors (20 Hz): no message at all for `link_timeout` (1.5 s: a lost link), HEARTBEAT older
than `heartbeat_timeout` (5 s: mode and armed state unknown), leaving OFFBOARD, tracking
error over `tracking_error_max`, and the live minimum separation. A flagged vehicle triggers the
policy: ``hold_all`` / ``land_all`` stop the mission (`MissionAborted`), ``land_faulty`` lands
that vehicle and carries on (the mission then does not count as completed).

Safety: nothing is armed before `run()`; every error path ends in `_secure`, which disarms
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
    ArmingRefused,
    CommandError,
    GcsError,
    LinkError,
    MissionAborted,
    ModeRefused,
    PlanRejected,
    VehicleTimeout,
)
from gcs.flight.fleetfile import FleetSpec, FlightOptions, VehicleSpec
from gcs.flight.link import LinkHub, VehicleLink, mavlink, result_name
from gcs.flight.record import FlightRecorder, measured_min_separation
from gcs.flight.setpoints import Setpoint, SetpointTrack, hold_track, plan_tracks, transfer_track
from gcs.flight.stream import Streamer, jitter_stats
from planner.verify import verify

__all__ = ["TRACKING_TOLERANCE_M", "FlightExecutor", "VehicleStatus"]

#: Documented bound on how much closer two vehicles may come in flight than the plan's R:
#: tracking error of each (centimetres on the mock) plus the skew between their position
#: reports. The end-to-end test checks the measured separation against R minus this.
TRACKING_TOLERANCE_M = 0.1
#: Phases in which a vehicle is (or may be) in the air.
_AIRBORNE = ("climbing", "at_start", "flying", "holding", "landing", "faulty", "hovering")
_MONITOR_PERIOD = 0.05
_MODE_RETRY_FOR = 5.0


@dataclass
class VehicleStatus:
    """The executor's view of one vehicle (see `FlightExecutor.snapshot`)."""

    spec: VehicleSpec
    index: int
    link: VehicleLink | None = None
    home: np.ndarray | None = None
    start_ned: np.ndarray | None = None
    goal_ned: np.ndarray | None = None
    phase: str = "pending"
    """pending, connected, arming, climbing, at_start, flying, holding, landing, landed,
    hovering (Hold at the end), faulty, stopped."""
    fault: str | None = None
    fault_time: float | None = None
    armed_by_us: bool = False
    arm_sent: bool = False
    """An arming command went out (it may have armed the vehicle even if we never saw it)."""
    expect_offboard: bool = False
    tracking_error: float = math.nan
    goal_error: float = math.nan
    last_mode: str | None = None
    last_armed: bool | None = None

    @property
    def id(self) -> str:
        return self.spec.id


class FlightExecutor:
    """One flight of a plan on a fleet; see the module docstring."""

    def __init__(self, plan: Any, fleet: FleetSpec, options: FlightOptions | None = None) -> None:
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
        specs = fleet.for_plan(plan.scenario.ids)
        self.vehicles = [VehicleStatus(spec, i) for i, spec in enumerate(specs)]
        self.recorder = FlightRecorder([s.id for s in specs], [s.system_id for s in specs])
        self.phase = "created"
        self.record: dict[str, Any] | None = None
        self.mission_start: float | None = None
        """GCS-clock time (s) of mission time 0."""
        self.min_separation_live = math.inf
        self.streamer: Streamer | None = None
        self._t0 = time.monotonic()
        self._hub: LinkHub | None = None
        self._tracks: list[SetpointTrack] = []
        self._flow: asyncio.Task[None] | None = None
        self._abort: tuple[str, str] | None = None
        self._secure_task: asyncio.Task[None] | None = None
        self._subscribers: list[asyncio.Queue[dict[str, Any] | None]] = []
        self._background: set[asyncio.Task[Any]] = set()
        self._task: asyncio.Task[dict[str, Any]] | None = None
        self._yaw_ned = frames.world_yaw_to_ned(self.options.yaw)
        self._separation_scale = np.asarray(plan.scenario.separation_scale, dtype=float)

    # ================================================================ public API

    def now(self) -> float:
        """Seconds on the GCS clock (0 when the mission object was made or started)."""
        return time.monotonic() - self._t0

    def mission_time(self) -> float | None:
        return None if self.mission_start is None else self.now() - self.mission_start

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
                "tracking_error": _finite_or_none(v.tracking_error),
            })
        return {
            "phase": self.phase,
            "mission_time": self.mission_time(),
            "horizon": self.plan.scenario.horizon,
            "min_separation_live": _finite_or_none(self.min_separation_live),
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
        self.streamer = Streamer(self.options.rate_hz, boot_epoch=self._t0)
        self.streamer.listeners.append(self._on_send)
        monitor: asyncio.Task[None] | None = None
        try:
            async with LinkHub() as hub:
                self._hub = hub
                try:
                    await self._open_links(hub)
                    if self._abort is not None:  # aborted while the links were opening
                        raise MissionAborted(self._abort[1])
                    self.streamer.start()
                    monitor = asyncio.create_task(self._monitor(), name="mission-monitor")
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
        for v in self.vehicles:
            v.start_ned = frames.world_to_ned(scenario.starts[v.index], v.home)
            v.goal_ned = frames.world_to_ned(scenario.goals[v.index], v.home)
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
        link = _link(v)
        ok = await link.wait_for(
            lambda t: t.heartbeat_time is not None and t.position_ned is not None,
            self.options.connect_timeout)
        if not ok:
            what = "HEARTBEAT" if link.telemetry.heartbeat_time is None else "LOCAL_POSITION_NED"
            raise VehicleTimeout(v.id, f"no {what} within {self.options.connect_timeout:g} s on "
                                       f"{v.spec.connection} (system id {v.spec.system_id})")
        tel = link.telemetry
        if tel.autopilot != mavlink.MAV_AUTOPILOT_PX4:
            raise LinkError(f"{v.id}: autopilot type {tel.autopilot} is not PX4 "
                            f"(MAV_AUTOPILOT_PX4 = {mavlink.MAV_AUTOPILOT_PX4})")
        if tel.armed:
            raise GcsError(f"{v.id}: already armed; refusing to take control of a vehicle that "
                           f"someone else armed")
        if v.home is None:
            await self._resolve_home(v)
        v.phase = "connected"
        self._emit(v.id, "connected", f"mode {tel.mode.name if tel.mode else '?'}, home "
                                      f"{np.round(v.home, 3).tolist()}")

    async def _resolve_home(self, v: VehicleStatus) -> None:
        """Home in the world frame from the vehicle's EKF origin and the fleet's world_origin."""
        link = _link(v)
        origin = self.fleet.world_origin
        assert origin is not None
        for attempt in range(3):
            with contextlib.suppress(CommandError):
                await link.request_message(mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)
            if await link.wait_for(lambda t: t.gps_origin is not None, 1.0 + attempt):
                break
        tel = link.telemetry
        if tel.gps_origin is not None:
            v.home = frames.geodetic_to_enu(frames.Geodetic(*tel.gps_origin), origin)
            source = "GPS_GLOBAL_ORIGIN"
        else:
            with contextlib.suppress(CommandError):
                await link.request_message(mavlink.MAVLINK_MSG_ID_HOME_POSITION)
            if not await link.wait_for(lambda t: t.home is not None, 3.0):
                raise VehicleTimeout(v.id, "reported neither GPS_GLOBAL_ORIGIN nor HOME_POSITION "
                                           "(needed to place it with world_origin)")
            assert tel.home is not None
            geodetic, local = tel.home
            # LOCAL_NED origin = home's position minus home's local offset
            v.home = (frames.geodetic_to_enu(frames.Geodetic(*geodetic), origin)
                      - frames.ned_vector_to_world(local))
            source = "HOME_POSITION"
        self.recorder.vehicles[v.id].home = v.home.tolist()
        self._emit(v.id, "home", f"from {source}: {np.round(v.home, 3).tolist()}")

    async def _prepare(self, v: VehicleStatus) -> None:
        link = _link(v)
        streamer = self._streamer()
        opts = self.options
        here = np.asarray(link.telemetry.position_ned, dtype=float)
        streamer.assign(v.id, link, hold_track(here, self._yaw_ned, opts.rate_hz))
        await asyncio.sleep(opts.prestream)
        v.phase = "arming"
        await self._set_mode(v, px4.OFFBOARD, retry_for=_MODE_RETRY_FOR)
        v.expect_offboard = True
        await self._arm(v)
        assert v.start_ned is not None
        track = transfer_track(here, v.start_ned, opts.climb_speed, self._yaw_ned, opts.rate_hz)
        streamer.assign(v.id, link, track)
        v.phase = "climbing"
        self._emit(v.id, "climb", f"to start, {track.duration:.1f} s")

    async def _set_mode(self, v: VehicleStatus, mode: px4.Px4Mode, retry_for: float = 0.0) -> None:
        link = _link(v)
        deadline = time.monotonic() + retry_for
        while True:
            result = await link.command(mavlink.MAV_CMD_DO_SET_MODE, mode.command_params)
            if result == mavlink.MAV_RESULT_ACCEPTED:
                if await link.wait_for(lambda t: t.mode == mode,
                                       self.options.heartbeat_timeout):
                    self._emit(v.id, "mode", f"{mode.name} confirmed")
                    return
                raise ModeRefused(v.id, mavlink.MAV_CMD_DO_SET_MODE, result,
                                  f"{mode.name} accepted but not shown in HEARTBEAT within "
                                  f"{self.options.heartbeat_timeout:g} s")
            if (result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
                    and time.monotonic() < deadline):
                await asyncio.sleep(0.5)
                continue
            raise ModeRefused(v.id, mavlink.MAV_CMD_DO_SET_MODE, result,
                              f"{mode.name} refused: {result_name(result)}"
                              f"{_last_text(link)}")

    async def _arm(self, v: VehicleStatus) -> None:
        link = _link(v)
        deadline = time.monotonic() + self.options.arm_timeout
        attempts = 0
        while True:
            attempts += 1
            v.arm_sent = True
            result = await link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,))
            if result == mavlink.MAV_RESULT_ACCEPTED:
                v.armed_by_us = True
                if await link.wait_for(lambda t: t.armed, self.options.heartbeat_timeout):
                    self._emit(v.id, "armed", f"after {attempts} attempt(s)")
                    return
                raise ArmingRefused(v.id, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, result,
                                    f"arming accepted but HEARTBEAT not armed within "
                                    f"{self.options.heartbeat_timeout:g} s")
            if result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED:
                if time.monotonic() + px4.ARM_TEMPORARILY_REJECTED_RETRY_S < deadline:
                    await asyncio.sleep(px4.ARM_TEMPORARILY_REJECTED_RETRY_S)
                    continue
                raise ArmingRefused(v.id, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, result,
                                    f"arming still TEMPORARILY_REJECTED after "
                                    f"{self.options.arm_timeout:g} s{_last_text(link)}")
            raise ArmingRefused(v.id, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, result,
                                f"arming refused: {result_name(result)}{_last_text(link)}")

    async def _gather(self) -> None:
        tol = self.options.start_tolerance
        deadline = time.monotonic() + self.options.gather_timeout
        streamer = self._streamer()
        while True:
            waiting = []
            for v in self.vehicles:
                assignment = streamer.assignments.get(v.id)
                done = (assignment is not None
                        and streamer.tick - assignment.start_tick >= len(assignment.track) - 1)
                error = self._distance_ned(v, v.start_ned)
                if done and error <= tol:
                    if v.phase != "at_start":
                        v.phase = "at_start"
                        self._emit(v.id, "at_start", f"{error:.3f} m from start")
                else:
                    waiting.append((v.id, error))
            if not waiting:
                return
            if time.monotonic() > deadline:
                vid, error = waiting[0]
                raise VehicleTimeout(vid, f"not within {tol:g} m of its start after "
                                          f"{self.options.gather_timeout:g} s "
                                          f"({error:.2f} m away)")
            await asyncio.sleep(_MONITOR_PERIOD)

    async def _fly_plan(self) -> None:
        streamer = self._streamer()
        start_tick = streamer.next_tick() + 1
        for v, track in zip(self.vehicles, self._tracks, strict=True):
            streamer.assign(v.id, _link(v), track, start_tick)
            v.phase = "flying"
        self.mission_start = streamer.tick_time(start_tick) - self._t0
        streamer.measuring = True
        self._emit(None, "mission_start", f"tick {start_tick}, horizon "
                                          f"{self.plan.scenario.horizon:g} s")
        horizon = self.plan.scenario.horizon
        await self._sleep_until_mission_time(horizon)
        for v in self.vehicles:
            if v.phase == "flying":
                v.phase = "holding"
        self._emit(None, "horizon", "plan ended, holding at the goals")
        await self._sleep_until_mission_time(horizon + self.options.hold_at_goal)
        streamer.measuring = False
        for v in self.vehicles:
            if v.fault is None:
                v.goal_error = self._distance_ned(v, v.goal_ned)
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
        await self._wait_disarmed([v for v in self.vehicles if v.phase == "landing"])

    # ================================================================ making safe

    async def _land(self, v: VehicleStatus) -> None:
        """NAV_LAND (falling back to DO_SET_MODE AUTO.LAND); streaming to it stops either way
        (PX4 lands on offboard loss if the command never arrived)."""
        link = _link(v)
        v.phase = "landing"
        v.expect_offboard = False
        try:
            result = await link.command(mavlink.MAV_CMD_NAV_LAND)
            if result != mavlink.MAV_RESULT_ACCEPTED:
                await self._set_mode(v, px4.LAND)
            self._emit(v.id, "land", "landing")
        except GcsError as exc:
            self._emit(v.id, "land_failed", f"{exc}; setpoints stopped, PX4's offboard-loss "
                                            f"failsafe will land it")
        finally:
            self._streamer().unassign(v.id)

    async def _hold(self, v: VehicleStatus) -> None:
        v.expect_offboard = False
        try:
            await self._set_mode(v, px4.HOLD)
            self._emit(v.id, "hold", "holding (PX4 Hold)")
        except GcsError as exc:
            self._emit(v.id, "hold_failed", f"{exc}; setpoints stopped, PX4's offboard-loss "
                                            f"failsafe takes over")
        finally:
            self._streamer().unassign(v.id)

    async def _secure(self, v: VehicleStatus, action: str) -> None:
        """Leave `v` safe: disarmed on the ground, landing, or (action hold) in Hold."""
        if v.link is None:
            return
        tel = v.link.telemetry
        streamer = self._streamer()
        if not tel.armed and not v.arm_sent:
            streamer.unassign(v.id)
            v.expect_offboard = False
            if v.phase not in ("landed",):
                v.phase = "stopped"
            return
        on_ground = v.phase in ("arming",) or (
            tel.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND)
        if on_ground:  # armed, or an arming command may have armed it: disarm
            v.expect_offboard = False
            try:
                result = await v.link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (0.0,))
                self._emit(v.id, "disarm", f"on the ground: {result_name(result)}")
            except GcsError as exc:
                result = None
                self._emit(v.id, "disarm_failed", str(exc))
            if result == mavlink.MAV_RESULT_ACCEPTED:
                streamer.unassign(v.id)
                v.phase = "stopped"
                return
            # refused (it has taken off after all) or unanswered: land it
        if action == "hold":
            await self._hold(v)
            v.phase = "hovering"
        else:
            await self._land(v)

    async def _secure_all(self, action: str) -> None:
        if self._secure_task is None:
            # Freeze every stream where it is, so nothing moves on along the plan meanwhile.
            # (An abort can come before run() made the streamer: then nothing streams, and
            # `_secure` skips the vehicles, none of which has a link yet.)
            streamer = self.streamer
            if streamer is not None:
                for vid, assignment in list(streamer.assignments.items()):
                    if assignment.last is not None:
                        streamer.assign(vid, assignment.link, hold_track(
                            assignment.last.position, assignment.last.yaw, streamer.rate))
            self._secure_task = asyncio.ensure_future(asyncio.gather(
                *(self._secure(v, action) for v in self.vehicles),
                return_exceptions=True))
        await asyncio.shield(self._secure_task)

    async def _make_safe(self) -> None:
        """After an error or abort: secure everyone, wait for landed vehicles to disarm."""
        action = self._abort[0] if self._abort is not None else "land"
        await self._secure_all(action)
        if action == "land":
            await self._wait_disarmed([v for v in self.vehicles if v.arm_sent])
        for v in self.vehicles:
            if v.link is not None and v.link.telemetry.armed and v.phase != "hovering":
                self._emit(v.id, "still_armed", "still armed: operator attention required")

    async def _wait_disarmed(self, vehicles: list[VehicleStatus]) -> None:
        deadline = time.monotonic() + self.options.land_timeout
        pending = [v for v in vehicles if v.link is not None]
        while pending and time.monotonic() < deadline:
            still = []
            for v in pending:
                assert v.link is not None
                tel = v.link.telemetry
                if v.link.link_age() > self.options.link_timeout:
                    self._emit(v.id, "disarm_unconfirmed",
                               "link lost: cannot confirm that it landed and disarmed")
                    continue
                stale = v.link.heartbeat_age() > self.options.heartbeat_timeout
                if stale and tel.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
                    v.phase = "landed"
                    self._emit(v.id, "disarm_unconfirmed",
                               "on the ground (EXTENDED_SYS_STATE), but no HEARTBEAT to "
                               "confirm that it disarmed")
                    continue
                if not tel.armed and not stale:
                    if v.phase == "landing":
                        v.phase = "landed"
                        self._emit(v.id, "landed", "landed and disarmed")
                else:
                    still.append(v)
            pending = still
            await asyncio.sleep(_MONITOR_PERIOD)
        for v in pending:
            self._emit(v.id, "not_disarmed", f"not disarmed within "
                                             f"{self.options.land_timeout:g} s")

    # ================================================================ monitoring

    async def _monitor(self) -> None:
        opts = self.options
        plan = self.plan
        while True:
            await asyncio.sleep(_MONITOR_PERIOD)
            if self._abort is not None:
                return
            now = time.monotonic()
            t_mission = self.mission_time()
            positions = {}
            for v in self.vehicles:
                link = v.link
                if link is None or v.home is None:
                    continue
                tel = link.telemetry
                if tel.position_ned is not None and tel.position_time is not None:
                    p = np.asarray(tel.position_ned) + np.asarray(tel.velocity_ned) * (
                        now - tel.position_time)
                    positions[v.id] = frames.ned_to_world(p, v.home)
                if not v.expect_offboard or v.fault is not None:
                    continue
                silent = link.link_age(now)
                age = link.heartbeat_age(now)
                if silent > opts.link_timeout:
                    self._flag(v, "link_lost", f"no message for {silent:.2f} s")
                # issue 8: a NaN/infinite position or velocity from the real peer (the link
                # never stores it) is a lost estimate: a fault, handled by the policy.
                elif (tel.invalid_estimate_time is not None
                      and now - tel.invalid_estimate_time <= opts.link_timeout):
                    self._flag(v, "estimate_invalid",
                               f"{tel.invalid_estimates} non-finite LOCAL_POSITION_NED")
                elif age > opts.heartbeat_timeout:
                    self._flag(v, "heartbeat_lost", f"no HEARTBEAT for {age:.2f} s")
                elif tel.mode != px4.OFFBOARD:
                    name = tel.mode.name if tel.mode is not None else "?"
                    self._flag(v, "left_offboard", f"mode is now {name}")
                elif (t_mission is not None and v.phase in ("flying", "holding")
                      and v.id in positions):
                    planned = plan.vehicles[v.index].sample(plan.scenario.dt, [t_mission])
                    v.tracking_error = float(np.linalg.norm(
                        positions[v.id] - planned.position[0]))
                    if not v.tracking_error <= opts.tracking_error_max:  # NaN never passes
                        self._flag(v, "tracking_error",
                                   f"{v.tracking_error:.2f} m from the plan "
                                   f"(bound {opts.tracking_error_max:g} m)")
            # Every vehicle in the air counts, a faulty one going down among the others too.
            airborne = [positions[v.id] for v in self.vehicles
                        if v.id in positions and v.phase in _AIRBORNE]
            if len(airborne) >= 2:
                pts = np.stack(airborne) / self._separation_scale
                i, j = np.triu_indices(len(pts), k=1)
                closest = float(np.min(np.linalg.norm(pts[i] - pts[j], axis=1)))
                self.min_separation_live = min(self.min_separation_live, closest)
                alarm = plan.scenario.min_separation - opts.separation_alarm
                if closest < alarm and self._abort is None:
                    # Two vehicles about to meet is nobody's single fault: stop everyone
                    # where they are (PX4 Hold) rather than send anyone down through others.
                    self._emit(None, "separation_alarm",
                               f"vehicles {closest:.2f} m apart (alarm below {alarm:.2f} m)")
                    self._spawn(self.abort("hold", f"separation {closest:.2f} m"))

    def _flag(self, v: VehicleStatus, kind: str, detail: str) -> None:
        v.fault = kind
        v.fault_time = self.now()
        v.phase = "faulty"
        policy = self.options.policy
        self._emit(v.id, "fault", f"{kind}: {detail} -> policy {policy}")
        if policy == "land_faulty":
            self._spawn(self._land(v))
        else:
            action = "hold" if policy == "hold_all" else "land"
            self._spawn(self.abort(action, f"{v.id} {kind} ({detail})"))

    def _spawn(self, coro: Awaitable[Any]) -> None:
        task = asyncio.ensure_future(coro)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    # ================================================================ recording

    def _on_send(self, vehicle_id: str, tick: int, setpoint: Setpoint, sent: float) -> None:
        self.recorder.vehicles[vehicle_id].add_setpoint(round(sent - self._t0, 5), tick,
                                                        setpoint)

    def _on_message(self, link: VehicleLink, msg: Any, now: float) -> None:
        kind = msg.get_type()
        v = self.vehicles[self._index_of(link.vehicle_id)]
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
        elif kind == "STATUSTEXT":
            self._emit(v.id, "statustext", str(msg.text).rstrip("\x00"))

    def _index_of(self, vehicle_id: str) -> int:
        for v in self.vehicles:
            if v.id == vehicle_id:
                return v.index
        raise KeyError(vehicle_id)

    def _emit(self, vehicle: str | None, kind: str, detail: str = "") -> None:
        event = self.recorder.event(self.now(), vehicle, kind, detail)
        for queue in self._subscribers:
            queue.put_nowait(event)

    def _finish_record(self, error: BaseException | None) -> None:
        opts = self.options
        scenario = self.plan.scenario
        self.recorder.meta = {
            "plan": scenario.to_dict(),
            "fleet": self.fleet.to_dict(),
            "options": opts.to_dict(),
            "mission_start": self.mission_start,
            "horizon": scenario.horizon,
            "error": None if error is None else {
                "type": type(error).__name__, "message": str(error) or type(error).__name__},
        }
        self.recorder.summary = self._summary(error)
        self.record = self.recorder.to_dict()

    def _summary(self, error: BaseException | None) -> dict[str, Any]:
        opts = self.options
        scenario = self.plan.scenario
        streamer = self.streamer
        out: dict[str, Any] = {
            "completed": False, "goal_error_max": None, "tracking_error_max": None,
            "min_separation_measured": None, "min_separation_planned": None,
            "setpoint_rate_hz": None, "jitter_p50_ms": None, "jitter_p99_ms": None,
            "missed_ticks": streamer.missed_ticks if streamer is not None else 0,
            "faults": {v.id: v.fault for v in self.vehicles if v.fault is not None},
            # issue 8: packets dropped per vehicle (pinning, signing) and garbage per link.
            "security": {v.id: {**v.link.telemetry.security.to_dict(),
                                "invalid_estimates": v.link.telemetry.invalid_estimates,
                                "link_garbage_datagrams": v.link.endpoint.garbage_datagrams}
                         for v in self.vehicles if v.link is not None},
        }
        if self.plan.verification is not None:
            out["min_separation_planned"] = self.plan.verification.min_separation_continuous
        if self.mission_start is None:
            return out
        t0 = self.mission_start
        end = t0 + scenario.horizon + opts.hold_at_goal
        first_fault = min((v.fault_time for v in self.vehicles if v.fault_time is not None),
                          default=math.inf)
        t1 = min(end, first_fault, self.now())
        tracking = []
        times, positions = [], []
        for v in self.vehicles:
            rec = self.recorder.vehicles[v.id]
            t, p = rec.telemetry_arrays()
            stop = min(t1, v.fault_time if v.fault_time is not None else math.inf)
            window = (t >= t0) & (t <= stop)
            if np.any(window):
                planned = self.plan.vehicles[v.index].sample(scenario.dt, t[window] - t0)
                tracking.append(float(np.max(np.linalg.norm(
                    p[window] - planned.position, axis=1))))
            times.append(t)
            positions.append(p)
        if tracking:
            out["tracking_error_max"] = max(tracking)
        # Separation over the whole flight, not only up to the first fault: a vehicle sent
        # down by land_faulty still passes the others.
        separation, _ = measured_min_separation(times, positions, t0, min(end, self.now()),
                                                opts.rate_hz, self._separation_scale)
        out["min_separation_measured"] = _finite_or_none(separation)
        goal_errors = [v.goal_error for v in self.vehicles if not math.isnan(v.goal_error)]
        if goal_errors:
            out["goal_error_max"] = max(goal_errors)
        if streamer is not None:
            counts = [sum(1 for s in self.recorder.vehicles[v.id].sp_t if t0 <= s <= t1)
                      for v in self.vehicles]
            if t1 > t0:
                out["setpoint_rate_hz"] = float(np.mean(counts)) / (t1 - t0)
            stats = jitter_stats(streamer.lateness)
            out["jitter_p50_ms"] = _finite_or_none(stats["jitter_p50_ms"])
            out["jitter_p99_ms"] = _finite_or_none(stats["jitter_p99_ms"])
        landed_ok = opts.at_end != "land" or all(v.phase == "landed" for v in self.vehicles)
        out["completed"] = bool(
            error is None and not out["faults"] and len(goal_errors) == len(self.vehicles)
            and max(goal_errors) <= opts.goal_tolerance and landed_ok)
        return out

    # ================================================================ helpers

    def _streamer(self) -> Streamer:
        assert self.streamer is not None
        return self.streamer

    def _distance_ned(self, v: VehicleStatus, target: np.ndarray | None) -> float:
        tel = _link(v).telemetry
        if tel.position_ned is None or target is None:
            return math.inf
        return float(np.linalg.norm(np.asarray(tel.position_ned) - target))

    async def _sleep_until_mission_time(self, t: float) -> None:
        assert self.mission_start is not None
        await asyncio.sleep(max(0.0, self.mission_start + t - self.now()))


def _link(v: VehicleStatus) -> VehicleLink:
    assert v.link is not None
    return v.link


def _last_text(link: VehicleLink) -> str:
    texts = link.telemetry.statustexts
    return f" (vehicle says: {texts[-1]!r})" if texts else ""


def _finite_or_none(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _cancelling() -> bool:
    task = asyncio.current_task()
    return task is not None and task.cancelling() > 0


async def _all(coros: Iterable[Awaitable[Any]]) -> None:
    """Run concurrently; on the first error cancel the rest and raise that error."""
    tasks = [asyncio.ensure_future(c) for c in coros]
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
