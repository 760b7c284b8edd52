"""The fleet executor: fly a plan on a fleet of PX4 and ArduPilot vehicles with one shared
flight clock.

Long: the flight's state, public API and order of phases, each a few lines over its parts.

`FlightExecutor(plan, fleet)` runs the whole flight on the caller's asyncio loop. It keeps the
flight's state (phase, abort, clock, streams) and the order of its phases; each part acts on
it through one protocol, `gcs.flight.run.state.RunningFlight`, and each step on a vehicle gets the
flight's `FlightContext` (`gcs.flight.procedure.context`). A setpoint goes
executor -> `Streamer` (one tick for the whole fleet) -> `VehicleLink` -> UDP.

1. connect (`gcs.flight.run.boarding`): open the fleet's links, wait for every vehicle's
   HEARTBEAT and position (refuse one already armed), place each home in the world frame,
   the pre-flight gate, the geofence, each vehicle's own link-loss failsafe;
2. board, per vehicle, concurrently: its autopilot's steps into the mode that follows
   setpoints, armed, climbing to the plan's start (`Autopilot.boarding`); vehicles whose
   homes are nearer than R horizontally climb in waves, the higher start first
   (`gcs.flight.run.climb_order`); one whose plan starts on the ground where it stands is
   armed, lifted off and landed by the plan's own waves (`gcs.flight.run.ground`);
3. when every vehicle is within `start_tolerance` of its start (`gcs.flight.run.arrival`),
   start the shared flight clock: every vehicle's setpoint for tick k leaves in tick k
   (`gcs.flight.timeline`); in-flight replans switch plans on it (`gcs.flight.replan`), and
   pauses stop it (`gcs.flight.run.pausing`);
4. after the horizon (of the last plan switched in), hold at the goals for `hold_at_goal`,
   judge the goal errors, then land and wait for the disarm, or Hold (`at_end`); goals
   stacked closer than R horizontally are left by a landing plan first.

The monitor (20 Hz, `gcs.flight.safety.monitor`) finds lost links, stale heartbeats, a vehicle
out of its mode, tracking errors and the live separation; `gcs.flight.run.faults` routes each
finding to the fault policy (`gcs.flight.safety.policy`: ``hold_all`` / ``land_all`` abort,
``land_faulty`` lands that vehicle and flies the others on, ``replan`` flies them around it).

Safety: nothing is armed before `run()`; every abort or error ends in
`gcs.flight.run.securing`: a verified landing plan where one is flown, else each vehicle
secured where it is (disarmed on the ground, Land or Hold in the air), then the wait for the
landed ones to disarm. A vehicle that does not answer gets no more setpoints, so its own
offboard-loss failsafe takes over.

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
from gcs.errors import FlightAborted, PlanRejected, StateConflict
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS
from gcs.flight.link.setpoints import SetpointTrack, plan_tracks
from gcs.flight.link.station import StallReport, StationStalls
from gcs.flight.procedure import endings
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.failsafe import restore_failsafe
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.replan import Replanner
from gcs.flight.run import arrival
from gcs.flight.run.boarding import connect_vehicle, fence_fleet, prepare_vehicle, set_failsafes
from gcs.flight.run.climb_order import climb_waves
from gcs.flight.run.events import EventFanout
from gcs.flight.run.faults import FaultRouter
from gcs.flight.run.ground import GroundShow
from gcs.flight.run.pausing import Pausing
from gcs.flight.run.precedence import abort_in_force, aborting_refusal
from gcs.flight.run.record import FlightRecorder
from gcs.flight.run.recording import FlightRecording, finish_record
from gcs.flight.run.securing import Securing
from gcs.flight.run.snapshot import flight_snapshot
from gcs.flight.safety.margin import check_margin, required_separation
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import FlownPlans
from gcs.flight.timeline.stream import Streamer
from gcs.geofence import build_fence
from gcs.phases import EventKind, FlightPhase, VehiclePhase
from gcs.tasks import all_or_first_error
from planner import Plan
from planner.verification.verify import refusal

__all__ = ["TRACKING_TOLERANCE_M", "FlightExecutor", "VehicleStatus"]

#: Documented bound on how much closer two vehicles may come in flight than the plan's R:
#: tracking error of each (centimetres on the mock) plus the skew between their position
#: reports. The end-to-end test checks the measured separation against R minus this.
TRACKING_TOLERANCE_M = 0.1


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
        """The flight clock (`gcs.flight.timeline.clock`); made again on the streamer's ticks by
        `run`."""
        self._events = EventFanout(self.recorder, self.now)
        self._recording = FlightRecording(self.recorder, {v.id: v for v in self.vehicles},
                                          lambda: self._t0, self._emit)
        self.stalls = StationStalls()
        """The station's own stalls (`gcs.flight.link.station`), not counted against vehicles."""
        self.stalls.listeners.append(self._on_stall)
        self._stall_report = StallReport()
        self.context = FlightContext(self.options, self._emit, self.stalls, self._stop_stream)
        """What the procedure's steps, the failsafe, the fault policy, the planned landing and
        the replans need of this flight (`gcs.flight.procedure.context`)."""
        self.aborting: tuple[str, str] | None = None
        """The abort in force, (action, reason) (`request_abort`), or None."""
        self.flown = FlownPlans.of(plan)
        """The plans the flight flies in flight time, and the motions off them
        (`gcs.flight.timeline.flown`): the first plan, then each switched replan's."""
        self.replanner: Replanner | None = None
        """The flight's in-flight replans (`gcs.flight.replan.replan`), once the plan is flown."""
        self._plan_changed = asyncio.Event()
        """Set when a replan switched: the end of the flight's plan moved."""
        self.streamer: Streamer | None = None
        self.tracks: list[SetpointTrack] = []
        """Each vehicle's plan track in force, in fleet order: the first plan's, spliced by each
        switched replan (a pause holds a vehicle only while it flies its one)."""
        self.faults = FaultRouter(self, self.now)
        """What the monitor finds and what the flight does about it (`gcs.flight.run.faults`)."""
        self.monitor = self.faults.monitor
        self.policy = self.faults.policy
        self.pausing = Pausing(self)
        self.securing = Securing(self)
        self._flow: asyncio.Task[None] | None = None
        self._task: asyncio.Task[dict[str, Any]] | None = None
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
        """Stop the shared flight clock; every vehicle flying the plan holds one plan time's
        setpoint (`gcs.flight.run.pausing.Pausing.pause`). Returns that plan time."""
        return self.pausing.pause(at)

    def resume(self) -> float:
        """Restart the shared flight clock where `pause` stopped it; returns that plan time.
        `StateConflict` unless paused."""
        return self.pausing.resume()

    def start(self) -> asyncio.Task[dict[str, Any]]:
        """Run the flight in a background task (on the running loop) and return the task."""
        if self._task is None:
            self._task = asyncio.create_task(self.run(), name="flight")
        return self._task

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        """Stop the flight now: every vehicle to land or to Hold at once.

        Returns once the commands were sent and answered (or timed out); `run()` then raises
        `FlightAborted` after waiting for landed vehicles to disarm. Conflicting aborts
        resolve as `request_abort` says.
        """
        self.request_abort(action, reason)
        assert self.aborting is not None
        await self.securing.secure_all(self.aborting[0])

    def request_abort(self, action: str, reason: str) -> None:
        """Accept an abort by the commands' precedence (`gcs.flight.run.precedence`), with an
        `abort` event, or refuse it (`StateConflict`, with a `command_refused` event): land
        overrides a hold under way (applied once the hold is sent), a hold is refused while
        the fleet lands, a repeat changes nothing. The vehicles are secured by `run()` (and
        by `abort`, which waits for it)."""
        current = None if self.aborting is None else self.aborting[0]
        try:
            in_force = abort_in_force(current, action,
                                      "" if self.aborting is None else self.aborting[1])
        except StateConflict as exc:
            self._emit(None, EventKind.COMMAND_REFUSED, f"{reason}: {action} all: {exc.reason}")
            raise
        if self.aborting is None:
            self.aborting = (action, reason)
            if self.replanner is not None:
                self.replanner.cancel("the flight is aborting")
            self.pausing.end()
            self._emit(None, EventKind.ABORT, f"{reason}: {action} all")
            if self._flow is not None and not self._flow.done():
                self._flow.cancel()
        elif in_force == current:
            self._emit(None, EventKind.ABORT, f"{reason}: {action} all (already under way: "
                                              f"{self.aborting[1]})")
        else:
            self._emit(None, EventKind.ABORT, f"{reason}: {action} all (overrides the "
                                              f"{current} of {self.aborting[1]})")
            self.aborting = (in_force, reason)

    def snapshot(self) -> FlightSnapshot:
        """JSON-ready live state (`gcs.flight.run.snapshot`): phase, flight time, per vehicle
        position (world frame), mode, armed, heartbeat age, tracking error, fault; live
        minimum separation."""
        return flight_snapshot(self.phase, self.flight_time(), self.flown.horizon,
                               self.monitor.min_separation, self.vehicles,
                               len(self.recorder.events),
                               replan=None if self.replanner is None
                               else self.replanner.current)

    @property
    def replans(self) -> list[ReplanDocument]:
        """Every replan object of the flight, in order (also the record's ``replans``)."""
        return [] if self.replanner is None else self.replanner.documents()

    @property
    def replan_lead(self) -> float | None:
        """Seconds from a replan request to its switch now (`gcs.flight.replan.replan`:
        `replan_lead_s`, or longer after a slow replan); None until the plan is flown."""
        return None if self.replanner is None else self.replanner.lead()

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
        replanner = self.replanner_now()
        return replanner.request(goals, drop, drop_action, reason)

    def replanner_now(self) -> Replanner:
        """The replanner, when a replan may start now; `StateConflict` otherwise."""
        if self.aborting is not None:
            raise aborting_refusal("replan", self.aborting[0])
        if (self.replanner is None or self.phase != FlightPhase.FLYING
                or self.clock.pause is not None):
            raise StateConflict("status", f"only a flying flight can be replanned (phase "
                                          f"{self.phase})")
        if (why := self.ground.replan_refusal()) is not None:
            raise StateConflict("status", why)
        return self.replanner

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
                try:
                    await self._open_links(hub)
                    if self.aborting is not None:  # aborted while the links were opening
                        raise FlightAborted(self.aborting[1])
                    self.streamer.start()
                    if self.streamer.realtime:
                        await asyncio.sleep(0)  # its first step sets the priority
                        self._emit(None, EventKind.STREAM_PRIORITY, self.streamer.scheduling)
                    monitor = asyncio.create_task(
                        self.monitor.run(lambda: self.aborting is not None
                                         and self.securing.landing is None),
                        name="flight-monitor")
                    self._flow = asyncio.create_task(self._fly(), name="flight-flow")
                    try:
                        await self._flow
                    except asyncio.CancelledError:
                        if self.aborting is None or _cancelling():
                            raise
                        raise FlightAborted(self.aborting[1]) from None
                except BaseException as exc:
                    error = exc
                    await self._failed(exc)
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
        self.phase = FlightPhase.CONNECTING
        origin = self.fleet.world_origin
        await all_or_first_error(connect_vehicle(v, self.context, origin, self.recorder,
                                                 take_over=self.take_over)
                                 for v in self.vehicles)
        await fence_fleet(self.vehicles, build_fence(self.plan.scenario.to_dict()),
                          self.context, origin)
        await set_failsafes(self.vehicles, self.plan, self.context, self.recorder)
        self.phase = FlightPhase.PREPARING
        await self._board()
        self.phase = FlightPhase.GATHERING
        await arrival.gather(self)
        self.phase = FlightPhase.FLYING
        await self._fly_plan()
        self.phase = FlightPhase.FINISHING
        await self.finish()
        self.phase = FlightPhase.FINISHED

    async def _board(self) -> None:
        """Every vehicle into the air and on its way to its start: in waves where one's
        climb passes another's column (`gcs.flight.run.climb_order`), those standing at
        their start on the ground armed for their takeoff (`gcs.flight.run.ground`)."""
        opts = self.options
        homes = [v.placed for v in self.vehicles]
        self.tracks = plan_tracks(self.plan, homes, opts.rate_hz, opts.yaw,
                                  extra_s=opts.hold_at_goal)
        scenario = self.plan.scenario
        goals = scenario.assigned_goals  # under free assignment, the goal each was given
        for v, home in zip(self.vehicles, homes, strict=True):
            v.start_ned = frames.world_to_ned(scenario.starts[v.index], home)
            v.goal_ned = frames.world_to_ned(goals[v.index], home)
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
            await all_or_first_error(prepare_vehicle(v, streamer, self.context, self._yaw_ned,
                                                     self.fleet.world_origin,
                                                     on_ground=self.ground.on_ground(v))
                                     for v in wave)
            if k < last:
                await arrival.gather(self, wave)
        await self.ground.board(self.vehicles, self.context)

    async def _fly_plan(self) -> None:
        streamer = self._streamer()
        start_tick = streamer.next_tick() + 1
        for v, track in zip(self.vehicles, self.tracks, strict=True):
            if self.ground.streams_from_start(v):
                streamer.assign(v.id, v.linked, track, start_tick)
            if not self.ground.on_ground(v):  # (one on the ground lifts off with its wave)
                v.phase = VehiclePhase.FLYING
        self.clock.begin(start_tick)
        streamer.measuring = True
        replanner = self.replanner = Replanner(
            self.plan.scenario.assigned(), self.vehicles, streamer, self.clock, self.context,
            self.flown, self.tracks, land=self._land,
            active=lambda: self.aborting is None, on_switch=self._plan_changed.set,
            on_missed=self.faults.replan_missed)
        self._emit(None, EventKind.FLIGHT_START, f"tick {start_tick}, horizon "
                                                 f"{self.plan.scenario.horizon:g} s")
        ground = asyncio.ensure_future(self.ground.fly(
            self.vehicles, self.tracks, streamer, self.clock, self.context,
            lambda why: self.request_abort("land", why)))
        try:
            await arrival.fly_to_plan_end(self, replanner, self._plan_changed)
            await ground  # every landing by the plan has ended
        finally:
            ground.cancel()
        self.recorder.goal_settle_s = await arrival.settle_at_goals(self)
        streamer.measuring = False
        judged = [v for v in self.vehicles if v.fault is None and v.dropped is None]
        for v in judged:
            v.goal_error = v.distance_ned(v.goal_ned)
            v.goal_tolerance = arrival.vehicle_goal_tolerance(self, v)
        self._emit(None, EventKind.GOAL_ERRORS, ", ".join(
            f"{v.id} {v.goal_error:.3f} m" for v in judged))

    async def finish(self) -> None:
        """The end of the flight: land (or hold, `at_end`) every vehicle still the plan's and
        wait for the landing ones to disarm."""
        # (a vehicle a replan dropped with land is handed to its Land by the replanner)
        live = [v for v in self.vehicles if v.fault is None and v.dropped != "land"
                and v.id not in self.ground.landed]  # (those the plan landed are down)
        if self.options.at_end == "hold":
            await all_or_first_error(endings.hold_vehicle(v, self.context) for v in live)
            for v in live:
                v.phase = VehiclePhase.HOVERING
        elif (landing := self.securing.end_landing(live, self.faults.descent)) is not None:
            await self.securing.fly(landing)
        else:
            await all_or_first_error(self._land(v) for v in live)
        # and the ones a land_faulty policy sent down, once their landing command has an
        # outcome (an unanswered one is given up on after its retries: land_failed)
        await asyncio.gather(*self.policy.landings, return_exceptions=True)
        if self.replanner is not None:
            await asyncio.gather(*self.replanner.landings, return_exceptions=True)
        await endings.wait_disarmed([v for v in self.vehicles
                                     if v.phase == VehiclePhase.LANDING], self.context)

    async def _failed(self, exc: BaseException) -> None:
        """The flight ended on `exc` (an abort or an error): record it and make the fleet
        safe; an error's landing is the abort in force then (a hold loses to it, and the
        clock does not wait on a pause)."""
        self.phase = (FlightPhase.ABORTED if isinstance(exc, FlightAborted)
                      else FlightPhase.FAILED)
        self._emit(None, EventKind.ERROR, f"{type(exc).__name__}: {exc}")
        if self.aborting is None:
            self.aborting = ("hold" if self.take_over else "land", f"{type(exc).__name__}: {exc}")
            self.pausing.end()
        await asyncio.shield(self.securing.make_safe())

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
        self.pausing.end()
        text = self._stall_report.flush(time.monotonic())
        if text is not None:
            self._emit(None, EventKind.STATION_STALL, text)
        self.record = finish_record(
            self.recorder, self.plan, self.fleet, self.options, self.vehicles,
            flight_start=self.flight_start, pauses=self.pauses, now=self.now(),
            margin=self.margin, streamer=self.streamer, error=error, flown=self.flown,
            replans=self.replans,
            flown_plans={} if self.replanner is None else self.replanner.flown_plans)

    # ================================================================ helpers

    def _land(self, v: VehicleStatus) -> Awaitable[None]:
        return endings.land_vehicle(v, self.context)

    def _stop_stream(self, vehicle_id: str) -> None:
        self._streamer().unassign(vehicle_id)

    def _streamer(self) -> Streamer:
        assert self.streamer is not None
        return self.streamer


def _cancelling() -> bool:
    task = asyncio.current_task()
    return task is not None and task.cancelling() > 0
