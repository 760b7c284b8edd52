"""The fleet executor: fly a plan on a fleet of PX4 vehicles with one shared flight clock.

`FlightExecutor(plan, fleet)` runs the whole flight on the caller's asyncio loop. It keeps the
orchestration of the phases; one vehicle's way into the air is `gcs.flight.run.boarding` (on the
PX4 procedure primitives of `gcs.flight.procedure.vehicle`), fault detection
`gcs.flight.safety.monitor`, what a fault does `gcs.flight.safety.policy`, the flight clock and its
pauses `gcs.flight.run.clock`, the live state `gcs.flight.run.snapshot`, the event fan-out
`gcs.flight.run.events`, the station's own stalls `gcs.flight.link.station`, what the links and
the streamer put in the record `gcs.flight.run.recording`, the record and its summary
`gcs.flight.run.record`, in-flight replans `gcs.flight.replan.replan` (the plans flown, in flight
time: `gcs.flight.run.flown`). A setpoint goes
executor -> `Streamer` (one tick for the whole fleet) -> `VehicleLink` -> UDP:

1. connect: open the fleet's links, send the GCS HEARTBEAT at 1 Hz, wait for every vehicle's
   HEARTBEAT and LOCAL_POSITION_NED (refuse a vehicle that is already armed or not PX4);
   place each vehicle's home in the world frame (fleet file, or `world_origin` and the
   vehicle's GPS_GLOBAL_ORIGIN / HOME_POSITION);
2. per vehicle, concurrently: stream setpoints holding its current position, then OFFBOARD
   (MAV_CMD_DO_SET_MODE, retried while TEMPORARILY_REJECTED), then arm (retried while
   TEMPORARILY_REJECTED, up to `arm_timeout`), each confirmed by COMMAND_ACK *and* HEARTBEAT;
   then climb vertically from home to the plan's start (then horizontally, if the home is not
   below the start); vehicles whose homes are nearer than R horizontally climb in waves, the
   higher start first (`gcs.flight.run.climb_order`). A vehicle whose plan starts on the
   ground where it stands is armed, lifted off and landed by the plan's own waves instead
   (`gcs.flight.run.ground`);
3. when every vehicle is within `start_tolerance` of its start, start the shared flight
   clock: every vehicle's setpoint for tick k leaves in tick k (`gcs.flight.run.stream.Streamer`);
4. after the horizon (of the last plan switched in by a replan), hold at the goals for
   `hold_at_goal`, measure the goal errors (each vehicle against its last goal; a dropped
   one is not judged), then land (MAV_CMD_NAV_LAND) and wait for the auto-disarm, or switch
   to Hold (`at_end`). Goals stacked closer than R horizontally are left by a landing plan
   first (`gcs.flight.safety.landing`), as an abort is: straight down, one would land under another.

Monitors (20 Hz, `gcs.flight.safety.monitor`): no message at all for `link_timeout` (1.5 s of
station-running time: a lost link), HEARTBEAT older than `heartbeat_timeout` (5 s: mode and
armed state unknown), leaving OFFBOARD, tracking error over `tracking_error_max`, and the live
minimum separation. A flagged vehicle triggers the policy: ``hold_all`` / ``land_all`` stop the
flight (`FlightAborted`), ``land_faulty`` lands that vehicle and carries on (the flight then
does not count as completed), ``replan`` lands it on its predicted motion and replans the
others around it (`gcs.flight.replan.replan`).

An abort with land (or an error) while the plan is flown flies a verified landing plan first
(`gcs.flight.safety.landing`): planned from the plan's state `landing_plan_timeout` ahead, streamed
like the plan, then PX4's Land at the touchdown points; PX4's Land straight away for vehicles
that cannot be steered, or for all when no plan is ready in time.

Safety: nothing is armed before `run()`; every error path ends in `endings.secure`, which disarms
armed vehicles still on the ground, sends airborne ones to land (or Hold for an explicit hold
abort), stops their streams, and waits for landed vehicles to disarm. A vehicle that does not
answer still gets no more setpoints, so PX4's own offboard-loss failsafe lands it.

Python API (for the CLI and the REST API)::

    flight = FlightExecutor(plan, fleet_spec, options)
    task = flight.start()                  # or: record = await flight.run()
    flight.snapshot()                      # JSON-ready live state (positions in world frame)
    async for event in flight.events():    # every event until the flight ends
        ...
    await flight.replan({"uav2": [x, y, z]}, drop=["uav3"])  # a new plan from a tick ahead
    await flight.abort("land")             # or "hold": all vehicles at once
    record = await task                    # the flight record (dict); also flight.record

`run()` returns the flight record when the flight ran to its end (check
``record["summary"]["completed"]``) and raises a `GcsError` (`ArmingRefused`, `FlightAborted`,
...) otherwise, after the vehicles were made safe; `flight.record` holds the record then too.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator, Awaitable, Mapping, Sequence
from typing import Any

import numpy as np

from gcs import frames
from gcs.documents import FlightEvent, FlightSnapshot, ReplanDocument
from gcs.errors import (
    FlightAborted,
    GcsError,
    PlanRejected,
    StateConflict,
    VehicleTimeout,
)
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS
from gcs.flight.link.setpoints import SetpointTrack, plan_tracks
from gcs.flight.link.station import STALL_NOTE_S, StallReport, StationStalls
from gcs.flight.procedure import endings
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.failsafe import (
    column_conflicts,
    failsafe_record,
    layer_delays,
    restore_failsafe,
    set_failsafe,
)
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.prediction import predicted_landing, stream_motion, unheard_margin
from gcs.flight.replan.replan import Replanner
from gcs.flight.run.boarding import connect_vehicle, fence_fleet, prepare_vehicle
from gcs.flight.run.climb_order import climb_waves
from gcs.flight.run.clock import FlightClock
from gcs.flight.run.events import EventFanout
from gcs.flight.run.flown import FlownPlans
from gcs.flight.run.ground import GroundShow
from gcs.flight.run.pausing import hold_fleet, release_fleet
from gcs.flight.run.precedence import abort_in_force, aborting_refusal
from gcs.flight.run.record import FlightRecorder, goal_tolerance
from gcs.flight.run.recording import FlightRecording, finish_record
from gcs.flight.run.snapshot import flight_snapshot
from gcs.flight.run.stream import Streamer
from gcs.flight.safety.descent import DescentConflict, descent_conflicts
from gcs.flight.safety.landing import SETTLE_S, PlannedLanding
from gcs.flight.safety.margin import check_margin, required_separation
from gcs.flight.safety.monitor import PERIOD, FleetMonitor
from gcs.flight.safety.policy import FaultPolicy
from gcs.flight.safety.silence import silent_hold
from gcs.geofence import build_fence
from gcs.phases import AIRBORNE, EventKind, FlightPhase, VehiclePhase
from gcs.tasks import all_or_first_error
from planner import Plan
from planner.verification.verify import refusal

__all__ = ["TRACKING_TOLERANCE_M", "FlightExecutor", "VehicleStatus"]

#: Documented bound on how much closer two vehicles may come in flight than the plan's R:
#: tracking error of each (centimetres on the mock) plus the skew between their position
#: reports. The end-to-end test checks the measured separation against R minus this.
TRACKING_TOLERANCE_M = 0.1
#: How often the hold at the goals looks again for vehicles still arriving (s).
SETTLE_POLL_S = 0.05


class FlightExecutor:
    """One flight of a plan on a fleet; see the module docstring."""

    def __init__(self, plan: Plan, fleet: FleetSpec, options: FlightOptions | None = None, *,
                 take_over: bool = False) -> None:
        """take_over: fly vehicles already armed (in the air, hovering where a lost station
        left them: `gcs.cli.land_plan`) instead of refusing them; an error then leaves the
        fleet in Hold rather than landing it straight down."""
        why = refusal(plan)  # verified again on the trajectories themselves
        if why is not None:
            raise PlanRejected(f"refusing to fly the plan: {why}")
        self.ground = GroundShow.of(plan, take_over=take_over)
        """The vehicles that take off from or land on the ground by the plan
        (`gcs.flight.run.ground`)."""
        self.plan = plan
        self.fleet = fleet
        self.options = options or fleet.options
        self.take_over = take_over
        self.margin = check_margin(plan, fleet.position_error)
        if not self.margin.ok and self.options.margin_check == "refuse":
            raise PlanRejected(f"refusing to fly: {self.margin.message()}")
        specs = fleet.for_plan(plan.scenario.ids)
        self.vehicles = [VehicleStatus(spec, i) for i, spec in enumerate(specs)]
        self.recorder = FlightRecorder([s.id for s in specs], [s.system_id for s in specs])
        self.phase = FlightPhase.CREATED
        self.record: dict[str, Any] | None = None
        self._t0 = time.monotonic()
        self.clock = FlightClock(self.options.rate_hz, self._t0, self._t0)
        """The flight clock (`gcs.flight.run.clock`); made again on the streamer's ticks by
        `run`."""
        self._events = EventFanout(self.recorder, self.now)
        self._recording = FlightRecording(self.recorder, {v.id: v for v in self.vehicles},
                                          lambda: self._t0, self._emit)
        self.stalls = StationStalls()
        """The station's own stalls (`gcs.flight.link.station`), not counted against vehicles."""
        self.stalls.listeners.append(self._on_stall)
        self._stall_report = StallReport()
        self.context = FlightContext(self.options, self._emit, self.stalls, self._stop_stream)
        """What the procedure's endings, the failsafe, the fault policy, the planned landing and
        the replans need of this flight (`gcs.flight.procedure.context`)."""
        self._abort: tuple[str, str] | None = None
        self.flown = FlownPlans.of(plan)
        """The plans the flight flies in flight time, and the motions off them
        (`gcs.flight.run.flown`): the first plan, then each switched replan's."""
        self._replanner: Replanner | None = None
        """The flight's in-flight replans (`gcs.flight.replan.replan`), once the plan is flown."""
        self._plan_changed = asyncio.Event()
        """Set when a replan switched: the end of the flight's plan moved."""
        self.policy = FaultPolicy(self.context, self.now, land=self._land_when_down,
                                  abort=self._fault_abort, aborting=lambda: self._abort is not None,
                                  descent=self._descent_conflicts,
                                  replan=self._replan_fault)
        self.monitor = FleetMonitor(self.vehicles, plan, self.options,
                                    flight_time=self.flight_time,
                                    on_fault=self._on_fault,
                                    planned=lambda v, times: self.flown.position(v.id, times),
                                    predicted=lambda v, t: self.flown.predicted(v.id, t),
                                    on_separation=lambda closest, alarm:
                                    self.policy.on_separation(
                                        closest, alarm, self.monitor.closest_text()),
                                    stalls=self.stalls,
                                    on_drops=lambda v, detail: self._emit(
                                        v.id, EventKind.DROPPED_PACKETS, detail),
                                    on_silent=self._on_silent, on_heard=self._on_heard,
                                    on_link=self._emit)
        self._silence_pause = False
        """The flight clock was stopped because a vehicle fell silent (`_on_silent`)."""
        self.streamer: Streamer | None = None
        self._hub: LinkHub | None = None
        self._tracks: list[SetpointTrack] = []
        self._flow: asyncio.Task[None] | None = None
        self._secure_task: asyncio.Future[Any] | None = None
        self._secure_action: str | None = None
        """The action `_secure_task` secures the vehicles with (land or hold)."""
        self._landing: PlannedLanding | None = None
        """The landing plan being flown after an abort with land (the monitor goes on)."""
        self._task: asyncio.Task[dict[str, Any]] | None = None
        self._pause_timer: asyncio.Future[None] | None = None
        self._yaw_ned = frames.world_yaw_to_ned(self.options.yaw)

    # ================================================================ public API

    def now(self) -> float:
        """Seconds on the GCS clock (0 when the executor was made or started)."""
        return time.monotonic() - self._t0

    def flight_time(self) -> float | None:
        """Seconds on the shared flight clock (None before it started); it stops while
        paused."""
        return self.clock.flight_time()

    @property
    def flight_start(self) -> float | None:
        """GCS-clock time (s) of flight time 0 (None before the plan started)."""
        return self.clock.start

    @property
    def pauses(self) -> list[list[float | None]]:
        """[start, end] of every pause (GCS clock, s; end None while paused)."""
        return self.clock.pauses

    @property
    def paused(self) -> bool:
        return self.clock.pause is not None

    def pause(self, at: float | None = None) -> float:
        """Stop the shared flight clock: from the next tick every vehicle flying the plan
        holds the plan's setpoint of that same plan time (at rest), so the fleet stays as
        separated as the plan is at that instant: the plan time reached, or `at` (flight
        time, s; `_on_silent` picks one near it). Returns the plan time it holds.
        `StateConflict` unless the plan is being flown (and not already paused). After
        `pause_limit` s the `pause_expiry` action (land or hold) ends the flight."""
        if self._abort is not None:
            raise aborting_refusal("pause", self._abort[0])
        if self.clock.pause is not None:
            raise StateConflict("status", "already paused")
        if self.phase != FlightPhase.FLYING or self.clock.start is None:
            raise StateConflict("status", f"only a flying flight can be paused (phase "
                                          f"{self.phase})")
        if self._replanner is not None:
            self._replanner.cancel("the flight was paused before the switch")
        streamer = self._streamer()
        pause = hold_fleet(streamer, self.clock, self.vehicles, self._tracks, at)
        self._pause_timer = asyncio.ensure_future(self._pause_limit())
        self.phase = FlightPhase.PAUSED
        t = pause.plan_tick / streamer.rate
        self._emit(None, EventKind.PAUSE, f"flight clock stopped at t={t:.2f} s; "
                                          f"{', '.join(pause.held)} holding (limit "
                                          f"{self.options.pause_limit:g} s, then "
                                          f"{self.options.pause_expiry})")
        return t

    def resume(self) -> float:
        """Restart the shared flight clock where `pause` stopped it; returns that plan time.
        `StateConflict` unless paused."""
        if self._abort is not None:
            raise aborting_refusal("resume", self._abort[0])
        if self.clock.pause is None:
            raise StateConflict("status", f"not paused (phase {self.phase})")
        self._silence_pause = False  # whoever resumes, the pause a silence made is over
        streamer = self._streamer()
        pause, paused = release_fleet(streamer, self.clock, self.vehicles, self._tracks)
        self._cancel_pause_timer()
        self.phase = FlightPhase.FLYING
        t = pause.plan_tick / streamer.rate
        self._emit(None, EventKind.RESUME, f"flight clock running again from t={t:.2f} s "
                                           f"after {paused:.1f} s")
        return t

    async def _pause_limit(self) -> None:
        await asyncio.sleep(self.options.pause_limit)
        action = self.options.pause_expiry
        self._emit(None, EventKind.PAUSE_LIMIT, f"paused for {self.options.pause_limit:g} s: "
                                                f"{action} all")
        await self.abort(action, f"paused longer than {self.options.pause_limit:g} s")

    def start(self) -> asyncio.Task[dict[str, Any]]:
        """Run the flight in a background task (on the running loop) and return the task."""
        if self._task is None:
            self._task = asyncio.create_task(self.run(), name="flight")
        return self._task

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        """Stop the flight now: every vehicle to land or to Hold (PX4 AUTO.LOITER) at once.

        Returns once the commands were sent and answered (or timed out); `run()` then raises
        `FlightAborted` after waiting for landed vehicles to disarm. Conflicting aborts
        resolve as `request_abort` says.
        """
        self.request_abort(action, reason)
        assert self._abort is not None
        await self._secure_all(self._abort[0])

    async def _fault_abort(self, action: str, reason: str) -> None:
        """A fault policy's abort: one that loses to an abort under way leaves only its
        `command_refused` event (nobody waits for an answer)."""
        with contextlib.suppress(StateConflict):
            await self.abort(action, reason)

    def request_abort(self, action: str, reason: str) -> None:
        """Accept an abort by the commands' precedence (`gcs.flight.run.precedence`), with an
        `abort` event, or refuse it (`StateConflict`, with a `command_refused` event): land
        overrides a hold under way (applied once the hold is sent), a hold is refused while
        the fleet lands, a repeat changes nothing. The vehicles are secured by `run()` (and
        by `abort`, which waits for it)."""
        current = None if self._abort is None else self._abort[0]
        try:
            in_force = abort_in_force(current, action,
                                      "" if self._abort is None else self._abort[1])
        except StateConflict as exc:
            self._emit(None, EventKind.COMMAND_REFUSED, f"{reason}: {action} all: {exc.reason}")
            raise
        if self._abort is None:
            self._abort = (action, reason)
            if self._replanner is not None:
                self._replanner.cancel("the flight is aborting")
            self._end_pause()
            self._emit(None, EventKind.ABORT, f"{reason}: {action} all")
            if self._flow is not None and not self._flow.done():
                self._flow.cancel()
        elif in_force == current:
            self._emit(None, EventKind.ABORT, f"{reason}: {action} all (already under way: "
                                              f"{self._abort[1]})")
        else:
            self._emit(None, EventKind.ABORT, f"{reason}: {action} all (overrides the "
                                              f"{current} of {self._abort[1]})")
            self._abort = (in_force, reason)

    def snapshot(self) -> FlightSnapshot:
        """JSON-ready live state (`gcs.flight.run.snapshot`): phase, flight time, per vehicle
        position (world frame), mode, armed, heartbeat age, tracking error, fault; live
        minimum separation."""
        return flight_snapshot(self.phase, self.flight_time(), self.flown.horizon,
                               self.monitor.min_separation, self.vehicles,
                               len(self.recorder.events),
                               replan=None if self._replanner is None
                               else self._replanner.current)

    @property
    def replans(self) -> list[ReplanDocument]:
        """Every replan object of the flight, in order (also the record's ``replans``)."""
        return [] if self._replanner is None else self._replanner.documents()

    @property
    def replan_lead(self) -> float | None:
        """Seconds from a replan request to its switch now (`gcs.flight.replan.replan`:
        `replan_lead_s`, or longer after a slow replan); None until the plan is flown."""
        return None if self._replanner is None else self._replanner.lead()

    @property
    def current_plan(self) -> Plan:
        """The plan the fleet flies now: the first, or the last switched replan's (its
        time 0 is ``flown.current.start`` in flight time)."""
        return self.flown.current.plan

    async def replan(self, goals: Mapping[str, Sequence[float]] | None = None,
                     drop: Sequence[str] = (), drop_action: str = "land",
                     reason: str | None = "operator") -> ReplanDocument:
        """Start an in-flight replan (`gcs.flight.replan.replan`): the vehicles named in `goals`
        fly to their new goal, the ones in `drop` land or hold (`drop_action`) on their own
        motion, the rest go on to their goals, all by one verified plan switched in at a
        stream tick ahead. Returns the replan object at once (status planning); the events
        say when it switched or why it missed. `StateConflict` unless the plan is flown (not
        paused, not aborting) and no other replan runs; `FieldError`s name ``goals.<id>``,
        ``drop[n]`` or ``drop_action``."""
        replanner = self._replanner_now()
        return replanner.request(goals, drop, drop_action, reason)

    def _replanner_now(self) -> Replanner:
        """The replanner, when a replan may start now; `StateConflict` otherwise."""
        if self._abort is not None:
            raise aborting_refusal("replan", self._abort[0])
        if (self._replanner is None or self.phase != FlightPhase.FLYING
                or self.clock.pause is not None):
            raise StateConflict("status", f"only a flying flight can be replanned (phase "
                                          f"{self.phase})")
        if (why := self.ground.replan_refusal()) is not None:
            raise StateConflict("status", why)
        return self._replanner

    def events(self) -> AsyncIterator[FlightEvent]:
        """Every event from now until the flight ends ({"t", "vehicle", "kind", "detail"})."""
        return self._events.events()

    async def run(self) -> dict[str, Any]:
        """Fly the plan; returns the flight record or raises a `GcsError` (see module)."""
        self._t0 = time.monotonic()
        error: BaseException | None = None
        if self.margin.needed is not None or self.margin.planned > 0:
            self._emit(None, EventKind.MARGIN if self.margin.ok else EventKind.MARGIN_WARNING,
                       self.margin.message())
        self.streamer = Streamer(self.options.rate_hz, boot_epoch=self._t0,
                                 realtime=self.options.stream_priority == "realtime")
        self.clock = FlightClock(self.options.rate_hz, self.streamer.epoch, self._t0)
        self.streamer.listeners.append(self._recording.on_send)
        self.streamer.stall_listeners.append(self.stalls.note)
        monitor: asyncio.Task[None] | None = None
        try:
            async with LinkHub(decode_ids=DECODED_IDS) as hub:
                self._hub = hub
                try:
                    await self._open_links(hub)
                    if self._abort is not None:  # aborted while the links were opening
                        raise FlightAborted(self._abort[1])
                    self.streamer.start()
                    if self.streamer.realtime:
                        await asyncio.sleep(0)  # its first step sets the priority
                        self._emit(None, EventKind.STREAM_PRIORITY, self.streamer.scheduling)
                    monitor = asyncio.create_task(
                        self.monitor.run(lambda: self._abort is not None
                                         and self._landing is None), name="flight-monitor")
                    self._flow = asyncio.create_task(self._fly(), name="flight-flow")
                    try:
                        await self._flow
                    except asyncio.CancelledError:
                        if self._abort is None or _cancelling():
                            raise
                        raise FlightAborted(self._abort[1]) from None
                except BaseException as exc:
                    error = exc
                    self.phase = (FlightPhase.ABORTED if isinstance(exc, FlightAborted)
                                  else FlightPhase.FAILED)
                    self._emit(None, EventKind.ERROR, f"{type(exc).__name__}: {exc}")
                    if self._abort is None:  # the landing an error starts is the abort in
                        # force: a hold loses to it, and the clock does not wait on a pause
                        self._abort = ("hold" if self.take_over else "land",
                                       f"{type(exc).__name__}: {exc}")
                        self._end_pause()
                    await asyncio.shield(self._make_safe())
                    raise
                finally:
                    if monitor is not None:
                        monitor.cancel()
                        with contextlib.suppress(asyncio.CancelledError):
                            await monitor
                    if not _cancelling():  # completed, aborted or failed: put them back
                        await asyncio.gather(*(restore_failsafe(v, self.context)
                                               for v in self.vehicles))
                    await self.streamer.stop()
        finally:
            self.close_record(error)
            self._events.close()
        assert self.record is not None
        return self.record

    # ================================================================ the flight

    async def _open_links(self, hub: LinkHub) -> None:
        for v in self.vehicles:
            # the fleet file's signing key and pinned peer
            v.link = await hub.add(v.id, v.spec.connection, v.spec.system_id,
                                   v.spec.component_id, signing_key=v.spec.signing_key,
                                   peer=v.spec.peer)
            v.link.listeners.append(self._recording.on_message)
            if v.spec.home is not None:
                v.home = np.asarray(v.spec.home, dtype=float)
                self.recorder.vehicles[v.id].home = v.home.tolist()

    async def _fly(self) -> None:
        opts = self.options
        self.phase = FlightPhase.CONNECTING
        await all_or_first_error(connect_vehicle(v, opts, self.fleet.world_origin, self.recorder,
                                   self._emit, self.stalls, take_over=self.take_over)
                   for v in self.vehicles)
        await fence_fleet(self.vehicles, build_fence(self.plan.scenario.to_dict()), opts,
                          self.fleet.world_origin, self._emit, self.stalls)
        await self._set_failsafes()
        homes = [v.placed for v in self.vehicles]
        self._tracks = plan_tracks(self.plan, homes, opts.rate_hz, opts.yaw,
                                   extra_s=opts.hold_at_goal)
        scenario = self.plan.scenario
        goals = scenario.assigned_goals  # under free assignment, the goal each was given
        for v, home in zip(self.vehicles, homes, strict=True):
            v.start_ned = frames.world_to_ned(scenario.starts[v.index], home)
            v.goal_ned = frames.world_to_ned(goals[v.index], home)
        self.phase = FlightPhase.PREPARING
        streamer = self._streamer()
        waves = climb_waves(homes, scenario.starts, required_separation(scenario),
                            scenario.separation_scale)
        last = max(waves, default=0)
        for k in range(last + 1):  # one whose column another's climb passes waits for it
            wave = [v for v, w in zip(self.vehicles, waves, strict=True) if w == k]
            for v in wave if k else ():
                self._emit(v.id, EventKind.CLIMB, f"climbs in wave {k + 1} of {last + 1}: a "
                                                  f"vehicle with a higher start stands nearer "
                                                  f"than R to its column")
            await all_or_first_error(prepare_vehicle(v, streamer, opts, self._yaw_ned, self._emit,
                                       self.stalls, self.fleet.world_origin,
                                       on_ground=self.ground.on_ground(v)) for v in wave)
            if k < last:
                await self._gather(wave)
        await self.ground.board(self.vehicles, opts, self._emit, self.stalls)
        self.phase = FlightPhase.GATHERING
        await self._gather()
        self.phase = FlightPhase.FLYING
        await self._fly_plan()
        self.phase = FlightPhase.FINISHING
        await self.finish()
        self.phase = FlightPhase.FINISHED

    async def _set_failsafes(self) -> None:
        """Before arming, each vehicle's own link-loss failsafe is set from the plan (Hold
        where its column meets another's, else Land by altitude layer, lowest first:
        `gcs.flight.procedure.failsafe`), told per vehicle and recorded; a vehicle that does
        not take it refuses the flight (`FailsafeNotSet`) unless the fleet option
        `failsafe` is `try`."""
        delays = layer_delays(self.plan, self.options.land_speed)
        conflicts = column_conflicts(self.plan, required_separation(self.plan.scenario))

        def why(vid: str) -> str:
            c = conflicts.get(vid)
            if c is None:
                return "its column keeps R from every other's"
            where = "onto" if c.above else "under"
            return (f"its column comes {c.gap:.2f} m from {c.other}'s at t={c.t:.1f} s: it "
                    f"hovers where the plan keeps R instead of landing {where} it")

        await asyncio.gather(*(set_failsafe(v, delays[v.index], v.id in conflicts, self.context,
                                            why=why(v.id))
                               for v in self.vehicles))
        for v in self.vehicles:
            self.recorder.vehicles[v.id].failsafe = {
                **failsafe_record(v.failsafe), "set": v.failsafe_before is not None,
                "why": why(v.id)}
        hovering = [v.id for v in self.vehicles if v.failsafe.effective == "Hold"]
        if hovering:
            self._emit(None, EventKind.FAILSAFE, (
                f"if the station is lost, {', '.join(hovering)} hover (their columns meet "
                f"others'); land them by plan from a station: fleetplan fleet land --plan "
                f"PLAN.json --fleet FLEET.json"))

    async def _gather(self, vehicles: Sequence[VehicleStatus] | None = None) -> None:
        """Until every vehicle (or those of `vehicles`) has flown its climb and is within
        `start_tolerance` of its start (`VehicleTimeout` after `gather_timeout`)."""
        tol = self.options.start_tolerance
        clock = self.stalls.clock  # the station's own stalls do not use up the timeout
        deadline = clock() + self.options.gather_timeout
        streamer = self._streamer()
        while True:
            waiting = []
            for v in self.vehicles if vehicles is None else vehicles:
                if self.ground.on_ground(v):  # at its start already (`GroundShow.board`)
                    continue
                assignment = streamer.assignments.get(v.id)
                done = (assignment is not None
                        and streamer.tick - assignment.start_tick >= len(assignment.track) - 1)
                error = v.distance_ned(v.start_ned)
                if done and error <= tol:
                    if v.phase != VehiclePhase.AT_START:
                        v.phase = VehiclePhase.AT_START
                        self._emit(v.id, EventKind.AT_START, f"{error:.3f} m from start")
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
            if self.ground.streams_from_start(v):
                streamer.assign(v.id, v.linked, track, start_tick)
            if not self.ground.on_ground(v):  # (one on the ground lifts off with its wave)
                v.phase = VehiclePhase.FLYING
        self.clock.begin(start_tick)
        streamer.measuring = True
        replanner = self._replanner = Replanner(
            self.plan.scenario.assigned(), self.vehicles, streamer, self.clock, self.context,
            self.flown, self._tracks, land=self._land,
            active=lambda: self._abort is None, on_switch=self._plan_changed.set,
            on_missed=self._replan_missed)
        self._emit(None, EventKind.FLIGHT_START, f"tick {start_tick}, horizon "
                                                 f"{self.plan.scenario.horizon:g} s")
        ground = asyncio.ensure_future(self.ground.fly(
            self.vehicles, self._tracks, streamer, self.clock, self.context,
            lambda why: self.request_abort("land", why)))
        try:
            await self._fly_to_plan_end(replanner)
            await ground  # every landing by the plan has ended
        finally:
            ground.cancel()
        await self._settle_at_goals()
        streamer.measuring = False
        judged = [v for v in self.vehicles if v.fault is None and v.dropped is None]
        for v in judged:
            v.goal_error = v.distance_ned(v.goal_ned)
            v.goal_tolerance = self._goal_tolerance(v)
        self._emit(None, EventKind.GOAL_ERRORS, ", ".join(
            f"{v.id} {v.goal_error:.3f} m" for v in judged))

    async def _fly_to_plan_end(self, replanner: Replanner) -> None:
        """Until the flight's plan (the last switched replan's) has ended and the hold at
        the goals is over."""
        while True:  # until the flight's plan (the last switched replan's) has ended
            if not await self._sleep_until_plan_end(0.0):
                continue
            for v in self.vehicles:
                if v.phase == VehiclePhase.FLYING:
                    v.phase = VehiclePhase.HOLDING
            self._emit(None, EventKind.HORIZON, "plan ended, holding at the goals")
            since = time.monotonic()
            if not await self._sleep_until_plan_end(self.options.hold_at_goal):
                continue
            # the hold lasts `hold_at_goal` of station-running time: a vehicle that got no
            # setpoints during a stall of the station is still catching up
            while (lost := self.stalls.overlap(since, checked := time.monotonic())) > 0:
                since = checked
                await asyncio.sleep(lost)
            segments = len(self.flown.segments)
            while replanner.job is not None:  # a replan on its way switches or misses
                await asyncio.sleep(PERIOD)
            if len(self.flown.segments) == segments:
                break

    async def _sleep_until_plan_end(self, extra: float) -> bool:
        """Sleep until `extra` s of flight time after the flight's plan ends; False as soon
        as a replan switched meanwhile (the end moved). A late wake-up is noted as a stall
        of the station (see `_sleep_until_flight_time`)."""
        segments = len(self.flown.segments)
        while len(self.flown.segments) == segments:
            now = self.flight_time()
            assert now is not None
            end = self.flown.horizon + extra
            if now >= end:
                return True
            self._plan_changed.clear()
            due = time.monotonic() + (end - now)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._plan_changed.wait(), end - now)
            woke = time.monotonic()
            if woke - due > STALL_NOTE_S:
                self.stalls.note(due, woke)
        return False

    def _goal_tolerance(self, v: VehicleStatus) -> float:
        """How close to its goal `v` must end, with the accuracy it reports now."""
        return goal_tolerance(self.options, self.fleet.position_error,
                              v.linked.telemetry.gps_h_acc)

    async def _settle_at_goals(self) -> None:
        """Hold on, up to `goal_settle_max`, while a healthy vehicle is not yet within its goal
        tolerance (the stream keeps it at its goal); the extension is recorded."""
        started = time.monotonic()

        def arriving() -> list[VehicleStatus]:
            return [v for v in self.vehicles if v.fault is None and v.dropped is None
                    and not v.distance_ned(v.goal_ned) <= self._goal_tolerance(v)]

        waited = 0.0
        while waited < self.options.goal_settle_max and arriving():
            await asyncio.sleep(SETTLE_POLL_S)
            waited = time.monotonic() - started
        self.recorder.goal_settle_s = waited

    async def finish(self) -> None:
        """The end of the flight: land (or hold, `at_end`) every vehicle still the plan's and
        wait for the landing ones to disarm."""
        # (a vehicle a replan dropped with land is handed to PX4's Land by the replanner)
        live = [v for v in self.vehicles if v.fault is None and v.dropped != "land"
                and v.id not in self.ground.landed]  # (those the plan landed are down)
        if self.options.at_end == "hold":
            await all_or_first_error(self._hold(v) for v in live)
            for v in live:
                v.phase = VehiclePhase.HOVERING
        elif (landing := self._end_landing(live)) is not None:
            self._landing = landing
            await landing.run()
        else:
            await all_or_first_error(self._land(v) for v in live)
        # and the ones a land_faulty policy sent down, once their landing command has an
        # outcome (an unanswered one is given up on after its retries: land_failed)
        await asyncio.gather(*self.policy.landings, return_exceptions=True)
        if self._replanner is not None:
            await asyncio.gather(*self._replanner.landings, return_exceptions=True)
        await endings.wait_disarmed([v for v in self.vehicles
                                     if v.phase == VehiclePhase.LANDING], self.context)

    # ================================================================ making safe

    def _land(self, v: VehicleStatus) -> Awaitable[None]:
        return endings.land_vehicle(v, self.context)

    def _descent_conflicts(self, v: VehicleStatus) -> list[DescentConflict] | None:
        """The others whose plan `v`'s straight descent from where it was last seen would
        come closer than R to (`gcs.flight.safety.descent`); None when that cannot be known (no
        position, or the plan's clock not started)."""
        now = self.flight_time()
        tel = None if v.link is None else v.link.telemetry
        if now is None or v.home is None or tel is None or tel.position_ned is None:
            return None
        position = frames.ned_to_world(tel.position_ned, v.home)
        if not np.all(np.isfinite(position)):
            return None
        flying = self.flown.current  # the plan in force: the first, or a switched replan's
        clearance = required_separation(self.plan.scenario)
        hold = 0.0
        if v.fault == "link_lost":  # on its own failsafe: it holds first, seen from afar
            age = self.stalls.age(tel.position_time, time.monotonic())
            # one that holds for good (ArduCopter without its GCS failsafe) is passed by the
            # others for the rest of the plan: its column counts for the whole plan
            hold = min(v.failsafe.hold_s, flying.plan.scenario.horizon)
            clearance += unheard_margin(age)
        return descent_conflicts(flying.plan, v.id, position, now - flying.start, clearance,
                                 ground=float(v.home[2]), hold=hold)

    def _on_silent(self, v: VehicleStatus, silent: float) -> None:
        """`v` has been unheard for `SILENT_HOLD_S`: stop the flight clock, so that the
        others stop on the plan where they keep the most room from where it stops on its
        own if its link is lost (it flies on to its last setpoint, then holds: PX4's
        failsafe; `gcs.flight.safety.silence`)."""
        if (self.phase != FlightPhase.FLYING or self._abort is not None
                or self.clock.pause is not None or self.clock.start is None):
            return
        t = self.pause(self._silent_hold(v))
        self._silence_pause = True
        self._emit(v.id, EventKind.LINK_SILENT, f"no message for {silent:.2f} s: the fleet "
                                                f"holds on the plan at t={t:.2f} s until it "
                                                f"is heard again or declared lost")

    def _silent_hold(self, v: VehicleStatus) -> float | None:
        """The flight time whose plan setpoints the others hold while `v` is silent (None:
        the one reached)."""
        now = self.clock.flight_time()
        motion = predicted_landing(v, self.plan.scenario, self.options, self.clock,
                                   measured=True, unheard=True)
        if now is None or motion is None:
            return None
        held, positions, velocities = [], [], []
        for u in self.vehicles:
            tel = u.link.telemetry if u.link is not None else None
            if (u.id == v.id or u.fault is not None or u.home is None or tel is None
                    or tel.position_ned is None):
                continue
            held.append(u.id)
            positions.append(frames.ned_to_world(tel.position_ned, u.home))
            velocities.append(frames.ned_vector_to_world(tel.velocity_ned or (0.0, 0.0, 0.0)))
        flying = self.flown.current
        return flying.start + silent_hold(
            flying.plan, lambda s: motion.position(now + s), now - flying.start, held,
            np.array(positions).reshape(-1, 3), np.array(velocities).reshape(-1, 3),
            self._streamer().rate)

    def _on_heard(self, v: VehicleStatus) -> None:
        """A silent vehicle is heard again: resume when nothing else keeps the fleet held."""
        if (self._silence_pause and not self.monitor.silent and self._abort is None
                and self.clock.pause is not None):
            self._silence_pause = False
            self._emit(v.id, EventKind.LINK_SILENT, "heard again: the flight goes on")
            self.resume()

    def _on_fault(self, v: VehicleStatus, kind: str, detail: str) -> None:
        """The monitor flagged `v`: a replan planned without knowing it is called off (under
        policy replan the new one is), then the policy acts."""
        if self._replanner is not None and self.options.policy != "replan":
            self._replanner.cancel(f"{v.id} faulted ({kind}) while it was planned")
        if self._silence_pause and self.options.policy in ("land_faulty", "replan") \
                and self.clock.pause is not None and self._abort is None:
            self._silence_pause = False  # these policies fly the others on
            self.resume()
        if kind == "link_lost" and v.phase in AIRBORNE and v.home is not None:
            # a moving obstacle for every plan made from now on, and what the separation
            # monitor counts for it while it is unheard
            motion = predicted_landing(v, self.plan.scenario.assigned(), self.options,
                                       self.clock, measured=True, unheard=True)
            if motion is not None:
                self.flown.motions[v.id] = motion
                stream_motion(self._streamer(), self.clock, v, motion, self.options.yaw)
        self.policy.on_fault(v, kind, detail)

    def _replan_fault(self, v: VehicleStatus, kind: str) -> None:
        """Policy replan: `v` lands on its own (PX4's Land; streamed its predicted motion
        meanwhile, in case it still listens) and the others replan around that motion; when
        they cannot, land_faulty's way (`FaultPolicy.give_way`)."""
        try:
            replanner = self._replanner_now()
        except GcsError as exc:
            replanner, why = None, exc.reason if isinstance(exc, StateConflict) else str(exc)
        if replanner is not None and not replanner.predict_landing(v, kind):
            replanner, why = None, "its motion cannot be predicted (no position)"
        self.policy.landings.append(self.policy.tasks.spawn(self._land_when_down(v)))
        if replanner is None:
            self._replan_missed([v], why)
            return
        with contextlib.suppress(Exception):  # on failure it fell back (`_replan_missed`)
            replanner.request(None, (), "land", f"{v.id} {kind}", faulty=[v])

    async def _land_when_down(self, v: VehicleStatus) -> None:
        """PX4's Land for a faulty vehicle: at once, or for a lost one once its predicted
        failsafe motion has ended (a Land arriving earlier would take it down before the
        hold the others were planned around was over)."""
        motion = self.flown.motions.get(v.id)
        if v.fault == "link_lost" and motion is not None:
            while (now := self.flight_time()) is not None and now < motion.end + SETTLE_S:
                await asyncio.sleep(min(PERIOD, motion.end + SETTLE_S - now))
        await self._land(v)

    def _replan_missed(self, faulty: list[VehicleStatus], why: str) -> None:
        """Policy replan could not fly the others around `faulty`: land_faulty's way."""
        for v in faulty:
            self._emit(v.id, EventKind.REPLAN_MISSED,
                       f"policy replan: no replan around it ({why}); land_faulty's way: the "
                       f"others fly on only where its descent is clear")
            self.policy.give_way(v)

    def _hold(self, v: VehicleStatus) -> Awaitable[None]:
        return endings.hold_vehicle(v, self.context)

    def _stop_stream(self, vehicle_id: str) -> None:
        self._streamer().unassign(vehicle_id)

    def _planned_landing(self, action: str) -> PlannedLanding | None:
        """The landing plan's run for an abort with land (`gcs.flight.safety.landing`), or None
        when nothing flies the plan (or `landing` is px4): then every vehicle gets PX4's Land
        where it is."""
        if action != "land" or self.options.landing != "planned" or self.streamer is None:
            return None
        landing = PlannedLanding(self.plan.scenario.assigned(), self.vehicles, self.streamer,
                                 self.context, self._secure_one, self.flown, self.clock)
        return landing if landing.eligible() else None

    def _end_landing(self, live: list[VehicleStatus]) -> PlannedLanding | None:
        """The landing plan for `at_end: land` when a vehicle's straight descent from its
        goal would come closer than R to another's goal (goals stacked above each other), or
        a vehicle off the plans is still in the air (it is planned around), or None: then
        PX4's Land takes each straight down, which keeps R."""
        if self.options.landing != "planned" or self.streamer is None:
            return None
        around = [v for v in self.vehicles if v not in live and v.phase in AIRBORNE]
        if not around and all(self._descent_conflicts(v) == [] for v in live):
            return None
        landing = PlannedLanding(self.plan.scenario.assigned(), live, self.streamer,
                                 self.context, self._land, self.flown, self.clock, around)
        return landing if landing.eligible() else None

    def _secure_one(self, v: VehicleStatus) -> Awaitable[None]:
        return endings.secure(v, "land", self.context)

    async def _secure_all(self, action: str) -> None:
        """Every vehicle to `action` (one securing per action: a land that overrides a hold
        under way starts once the hold's commands were answered)."""
        if self._secure_task is None or self._secure_action != action:
            previous = self._secure_task
            self._secure_action = action
            self._secure_task = asyncio.ensure_future(self._secure_after(previous, action))
        await asyncio.shield(self._secure_task)

    async def _secure_after(self, previous: asyncio.Future[Any] | None, action: str) -> None:
        if previous is not None:
            await asyncio.gather(previous, return_exceptions=True)
        if landing := self._planned_landing(action):
            self._landing = landing
            await landing.run()
        else:
            # Freeze every stream where it is, so nothing moves on along the plan meanwhile.
            # (An abort can come before run() made the streamer: then nothing streams, and
            # `secure` skips the vehicles, none of which has a link yet.)
            if self.streamer is not None:
                self.streamer.freeze()
            await asyncio.gather(
                *(endings.secure(v, action, self.context) for v in self.vehicles),
                return_exceptions=True)

    async def _make_safe(self) -> None:
        """After an error or abort: secure everyone (again if a land overrode a hold
        meanwhile), wait for landed vehicles to disarm."""
        while True:
            action = self._abort[0] if self._abort is not None else "land"
            await self._secure_all(action)
            if self._abort is None or self._abort[0] == action:
                break
        if action == "land":
            await endings.wait_disarmed([v for v in self.vehicles if v.arm_sent], self.context)
        for v in self.vehicles:
            if (v.link is not None and v.link.telemetry.armed
                    and v.phase != VehiclePhase.HOVERING):
                self._emit(v.id, EventKind.STILL_ARMED, "still armed: operator attention required")

    # ================================================================ recording

    def _on_stall(self, start: float, end: float) -> None:
        text = self._stall_report.add(start, end)
        if text is not None:
            self._emit(None, EventKind.STATION_STALL, text)

    def _emit(self, vehicle: str | None, kind: EventKind, detail: str = "") -> None:
        self._events.emit(vehicle, kind, detail)

    def close_record(self, error: BaseException | None) -> None:
        """Write the flight record (`self.record`) as the flight ended, with `error` if it
        ended on one."""
        self._end_pause()
        text = self._stall_report.flush(time.monotonic())
        if text is not None:
            self._emit(None, EventKind.STATION_STALL, text)
        self.record = finish_record(
            self.recorder, self.plan, self.fleet, self.options, self.vehicles,
            flight_start=self.flight_start, pauses=self.pauses, now=self.now(),
            margin=self.margin, streamer=self.streamer, error=error, flown=self.flown,
            replans=self.replans,
            flown_plans={} if self._replanner is None else self._replanner.flown_plans)

    # ================================================================ helpers

    def _streamer(self) -> Streamer:
        assert self.streamer is not None
        return self.streamer

    async def _sleep_until_flight_time(self, t: float) -> None:
        """Sleep until flight time `t`; a pause on the way makes it wait longer (the flight
        clock never runs faster than the GCS clock, so sleeping the remainder never
        oversleeps). A late wake-up is noted as a stall of the station at once, so that the
        goal errors judged next wait for it even before the monitor or streamer saw it."""
        while True:
            now = self.flight_time()
            assert now is not None
            if now >= t:
                return
            due = time.monotonic() + (t - now)
            await asyncio.sleep(t - now)
            woke = time.monotonic()
            if woke - due > STALL_NOTE_S:
                self.stalls.note(due, woke)

    def _end_pause(self) -> None:
        """Forget a pause (the flight is ending)."""
        self.clock.end_pause()
        self._cancel_pause_timer()

    def _cancel_pause_timer(self) -> None:
        if self._pause_timer is not None:
            self._pause_timer.cancel()
            self._pause_timer = None


def _cancelling() -> bool:
    task = asyncio.current_task()
    return task is not None and task.cancelling() > 0
