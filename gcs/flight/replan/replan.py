"""Replanning in flight: new goals, dropped vehicles, a faulty vehicle flown around.

Long: one class, `Replanner`: a replan's lifecycle from request to switch or miss.

`Replanner.request` starts one replan of a flying fleet (`FlightExecutor.replan`, the fault
policy ``replan``) and returns its replan object at once (status ``planning``):

1. it picks a switch tick ahead: the lead is the larger of `replan_lead_s` and 1.5 x the
   flight's last replan's planning time, and the switch tick the last stream tick within
   it (at least two ticks ahead); the state of every
   steered vehicle at that tick is its stream's setpoint then (the flying plan's exact
   state), in the world frame, so the setpoints stay continuous across the switch;
2. from that tick each dropped vehicle is streamed its own predicted motion
   (`planner.model.fixed.dropped_motion`: it coasts a step, then brakes and holds, or lands down
   to `landing_height` above the workspace floor at `land_speed`, then PX4's Land); every
   vehicle off the plans still in the air (a dropped one, a faulty one that PX4 lands, with
   a margin for the uncertain prediction) is given to the planner as fixed, so the others
   keep R from it and the verification covers it;
3. it plans (`planner.methods.replan.plan_replan`, verified) in a worker thread while the streams go
   on along the flying plan; a plan ready and verified before the switch tick is queued with
   `Streamer.switch` at exactly that tick (its tracks are the flying plan's ticks up to
   there, then the new plan's); at the tick the flight's plan becomes the new plan
   (`gcs.flight.timeline.flown`): its end, the goals each vehicle is judged against, the tracking
   the monitor checks.

A plan not ready and verified in time is not flown: the fleet goes on with its plan, status
``missed``, and the `replan_missed` event says why. One replan at a time: another request
while one plans is refused (`StateConflict`), not queued; a fault, a pause or an abort
before the switch tick calls the waiting replan off (``missed``).
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gcs import frames
from gcs.documents import ReplanDocument
from gcs.errors import InvalidRequest, StateConflict
from gcs.flight.link.setpoints import SetpointTrack, plan_tracks, spliced
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.flight.replan.prediction import (
    braking_deceleration,
    hardest_braking,
    motion_track,
    predicted_landing,
    stream_motion,
)
from gcs.flight.replan.record import ReplanRecord, Switch
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import FlownPlans, Motion, shifted
from gcs.flight.timeline.stream import Streamer
from gcs.phases import AIRBORNE, DropAction, EventKind, VehiclePhase
from gcs.replan_request import check_entries
from gcs.tasks import TaskSet
from planner.methods.replan import Replan, ReplanError, check_goals, plan_replan
from planner.model.fixed import FixedTrajectory, dropped_motion
from planner.model.scenario import Scenario
from planner.types import FloatArray

__all__ = ["LEAD_FACTOR", "Replanner"]

#: The lead is at least this many times the flight's last replan's planning time.
LEAD_FACTOR = 1.5
#: Ticks kept free between the plan being ready and its switch tick (to build the tracks).
SWITCH_MARGIN_TICKS = 1
#: After its streamed descent, a dropped vehicle gets this long to settle before PX4's Land.
SETTLE_S = 0.3
#: A switch tick the stream has not reached this long after its instant never comes (s).
STREAM_GONE_S = 5.0
#: How often the wait for the switch tick and for a descent's end looks at the clock (s).
POLL_S = 0.02


@dataclass
class Job:
    """One replan under way."""

    record: ReplanRecord
    """What the flight shows of it (`ReplanRecord.document`)."""
    tick: int
    """Streamer tick of the switch."""
    plan_tick: int
    """Flight tick of the switch (flight time x rate)."""
    steer: list[VehicleStatus]
    goals: FloatArray
    """(N, 3) world goals of `steer`, in order."""
    drop: list[VehicleStatus]
    action: DropAction
    drops: dict[str, Motion]
    """The dropped vehicles' streamed motions from the switch."""
    faulty: list[VehicleStatus] = field(default_factory=list)
    """Faulty vehicles the replan flies the others around (policy replan)."""
    switches: list[str] = field(default_factory=list)
    """Vehicles whose switch waits in the streamer."""
    result: Replan | None = None
    tracks: dict[str, SetpointTrack] = field(default_factory=dict)
    requested: float = field(default_factory=time.monotonic)
    """When it was asked for (`time.monotonic`)."""


class Replanner:
    """The in-flight replans of one flight (see the module)."""

    def __init__(self, base: Scenario, vehicles: list[VehicleStatus], streamer: Streamer,
                 clock: FlightClock, context: FlightContext, flown: FlownPlans,
                 tracks: list[SetpointTrack], *,
                 land: Callable[[VehicleStatus], Awaitable[None]],
                 active: Callable[[], bool],
                 on_switch: Callable[[], None] = lambda: None,
                 on_missed: Callable[[list[VehicleStatus], str], None] = lambda f, w: None
                 ) -> None:
        self.base = base
        """The flight's scenario (assigned goals): workspace, boxes, R, obstacles, dt."""
        self.vehicles = vehicles
        self.streamer = streamer
        self.clock = clock
        self.options = context.options
        self.emit: Emit = context.emit
        self.flown = flown
        self.tracks = tracks
        """The executor's plan tracks, one per vehicle (flight-tick indexed); a switch
        replaces a vehicle's in place."""
        self.land = land
        """PX4's Land for one vehicle (its stream stops once answered)."""
        self.active = active
        """False once the flight is aborting: no handover to PX4's Land from here."""
        self.on_switch = on_switch
        self.on_missed = on_missed
        """Called with the faulty vehicles of a missed replan (policy replan) and why."""
        self.goals: dict[str, FloatArray] = {
            vid: np.asarray(g, dtype=float)
            for vid, g in zip(base.ids, base.assigned_goals, strict=True)}
        """Every vehicle's current goal (world frame)."""
        self.records: list[ReplanRecord] = []
        """Every replan of the flight, in order."""
        self.flown_plans: dict[int, dict[str, Any]] = {}
        """Per switched replan id: its plan document and switch instant (for the record)."""
        self.landings: list[asyncio.Future[None]] = []
        """The dropped vehicles' handovers to PX4's Land (the flight's end waits for them)."""
        self.job: Job | None = None
        self.tasks = TaskSet()
        """The replans' waits for their switch and the dropped vehicles' handovers."""
        self._thread: asyncio.Future[Replan] | None = None
        self._last_planning: float | None = None

    # ------------------------------------------------------------------ state

    @property
    def current(self) -> ReplanDocument | None:
        """The running replan object, or the last one (None before any)."""
        return self.records[-1].document() if self.records else None

    def documents(self) -> list[ReplanDocument]:
        """Every replan object of the flight, in order."""
        return [r.document() for r in self.records]

    @property
    def busy(self) -> bool:
        """A replan plans or waits for its switch, or a late one's planning still runs."""
        return self.job is not None or (self._thread is not None and not self._thread.done())

    def steered(self, v: VehicleStatus) -> bool:
        """True when `v` flies the flight's plan (a replan can give it a new one)."""
        assignment = self.streamer.assignments.get(v.id)
        return (v.fault is None and v.dropped is None and v.link is not None
                and v.home is not None
                and v.phase in (VehiclePhase.FLYING, VehiclePhase.HOLDING)
                and assignment is not None and assignment.track is self.tracks[v.index]
                and assignment.start_tick == self.clock.start_tick
                and v.id not in self.streamer.pending)

    def lead(self) -> float:
        """Seconds from a request to its switch: `replan_lead_s`, or 1.5 x the last
        planning time when that is longer."""
        lead = self.options.replan_lead_s
        if self._last_planning is not None:
            lead = max(lead, LEAD_FACTOR * self._last_planning)
        return lead

    # ------------------------------------------------------------------ requests

    def request(self, goals: Mapping[str, Sequence[float]] | None = None,
                drop: Sequence[str] = (), drop_action: str = "land",
                reason: str | None = "operator", *,
                faulty: Sequence[VehicleStatus] = ()) -> ReplanDocument:
        """Start a replan; returns its object (status planning). `faulty`: vehicles that
        faulted and land on their own motion (policy replan): a replan for them calls off
        the one under way instead of being refused. Raises `StateConflict` while another
        runs (or nothing flies the plan), `InvalidRequest`/`ScenarioError` (FieldErrors)
        naming ``goals.<id>``, ``drop[n]`` or ``drop_action``."""
        if faulty:
            # the replan under way does not know of them: called off, and its own faulty
            # vehicles (if any) are flown around by this one instead
            carried = [] if self.job is None else self.job.faulty
            self.cancel(f"{', '.join(v.id for v in faulty)} faulted while it was planned",
                        fallback=False)
            faulty = [*(v for v in carried if v.dropped is None and v not in faulty), *faulty]
            try:
                return self._start(goals, drop, drop_action, reason, faulty)
            except Exception as exc:  # nothing to fly them around: land_faulty's way
                self.on_missed(list(faulty), f"cannot replan: {exc}")
                raise
        if self.busy:
            raise StateConflict("replan", "a replan is already running (refused, not "
                                          "queued): wait for it to switch or miss")
        return self._start(goals, drop, drop_action, reason, ())

    def _start(self, goals: Mapping[str, Sequence[float]] | None, drop: Sequence[str],
               drop_action: str, reason: str | None, faulty: Sequence[VehicleStatus]
               ) -> ReplanDocument:
        """`request` once it may start: check the fields, pick the switch tick and the
        states there, start planning."""
        action = check_entries(goals, drop, drop_action)
        by_id = {v.id: v for v in self.vehicles}
        steer = [v for v in self.vehicles if self.steered(v)]
        dropped = self._dropped(drop, by_id, steer)
        steer = [v for v in steer if v not in dropped]
        if not steer:
            raise InvalidRequest("drop", "would leave no vehicle on the plan: abort the "
                                         "flight instead")
        new_goals = self._goals(goals or {}, by_id, steer)
        streamer = self.streamer
        rate = streamer.rate
        lead = self.lead()
        # the last tick within the lead (the switch never comes later than asked), and
        # never so soon that no tick is left to build the tracks
        tick = max(streamer.next_tick() + SWITCH_MARGIN_TICKS,
                   math.floor((time.monotonic() + lead - streamer.epoch) * rate + 1e-9))
        plan_tick = tick - self.clock.start_tick
        t_switch = plan_tick / rate
        positions, velocities, accelerations = (np.array(x) for x in zip(
            *(self._setpoint_state(v, plan_tick) for v in steer), strict=True))
        drops = {v.id: Motion(t_switch, self._drop_motion(v, plan_tick, drop_action),
                              self.base.dt, True) for v in dropped}
        fixed = [m.trajectory for m in drops.values()]
        fixed += [shifted(self.flown.motions[v.id], t_switch)
                  for v in self._off_plan(steer + dropped)]
        goal_array = np.array([new_goals.get(v.id, self.goals[v.id]) for v in steer])
        now = self.clock.flight_time()
        record = ReplanRecord(
            id=len(self.records) + 1, requested_at=None if now is None else round(now, 3),
            switch_time=round(t_switch, 4), switch_tick=tick, lead_s=round(lead, 3),
            goals={vid: [float(c) for c in g] for vid, g in new_goals.items()},
            drop=[v.id for v in dropped], drop_action=action, reason=reason,
            vehicles=[v.id for v in steer], fixed=[f.id for f in fixed],
            faulty=[v.id for v in faulty])
        job = Job(record, tick, plan_tick, steer, goal_array, dropped, action, drops,
                  list(faulty))
        self.records.append(record)
        self.job = job
        self.emit(None, EventKind.REPLAN_STARTED, _started_text(record))
        self._thread = asyncio.ensure_future(asyncio.to_thread(
            plan_replan, self.base, [v.id for v in steer], positions, velocities,
            accelerations, goal_array, fixed=fixed,
            deadline=time.perf_counter() + max(0.0, streamer.tick_time(tick)
                                               - time.monotonic())))
        began = time.perf_counter()
        self._thread.add_done_callback(lambda fut: self._planned(record, fut, began))
        self.tasks.spawn(self._run(job, self._thread))
        return record.document()

    def _dropped(self, drop: Sequence[str], by_id: Mapping[str, VehicleStatus],
                 steer: list[VehicleStatus]) -> list[VehicleStatus]:
        out: list[VehicleStatus] = []
        for n, vid in enumerate(drop):
            where = f"drop[{n}]"
            v = by_id.get(vid)
            if v is None:
                raise InvalidRequest(where, f"no vehicle {vid!r} in this flight")
            if v not in steer:
                raise InvalidRequest(where, f"{vid!r} does not fly the plan ({_state(v)})")
            out.append(v)
        return out

    def _goals(self, goals: Mapping[str, Sequence[float]], by_id: Mapping[str, VehicleStatus],
               steer: list[VehicleStatus]) -> dict[str, FloatArray]:
        for vid in goals:
            v = by_id.get(vid)
            if v is None:
                raise InvalidRequest(f"goals.{vid}", f"no vehicle {vid!r} in this flight")
            if v not in steer:
                raise InvalidRequest(f"goals.{vid}", f"{vid!r} does not fly the plan "
                                                     f"({_state(v)})")
        others: dict[str, FloatArray] = {v.id: self.goals[v.id] for v in steer
                                         if v.id not in goals}
        # where the vehicles off the plans come to rest: no goal may be taken there
        for vid, motion in self.flown.motions.items():
            if by_id[vid].phase in AIRBORNE and vid not in goals:
                others.setdefault(vid, motion.trajectory.positions[-1])
        return check_goals(self.base, goals, others) if goals else {}

    def _setpoint_state(self, v: VehicleStatus, plan_tick: int) -> tuple[FloatArray, ...]:
        """(position, velocity, acceleration) in the world frame of `v` at flight tick
        `plan_tick`: its plan track's setpoint then."""
        sp = self.tracks[v.index].at(plan_tick)
        return (frames.ned_to_world(sp.position, v.placed),
                frames.ned_vector_to_world(sp.velocity),
                frames.ned_vector_to_world(sp.acceleration))

    def _drop_motion(self, v: VehicleStatus, plan_tick: int, action: str) -> FixedTrajectory:
        p, vel, acc = self._setpoint_state(v, plan_tick)
        lim = self.base.limits
        floor = float(lim.position_min[2]) + self.options.landing_height
        return dropped_motion(v.id, p, vel, acc, self.base.dt, action,
                              deceleration=braking_deceleration(self.base),
                              hardest=hardest_braking(self.base),
                              low=lim.position_min, high=lim.position_max,
                              descent_speed=self.options.land_speed,
                              floor=min(floor, float(p[2])))

    def _off_plan(self, steer: list[VehicleStatus]) -> list[VehicleStatus]:
        """The vehicles in the air that no plan steers, each with a known motion (one
        without is predicted landing from where it was last measured)."""
        out = []
        for v in self.vehicles:
            if v in steer or v.phase not in AIRBORNE:
                continue
            if v.id not in self.flown.motions:
                motion = predicted_landing(v, self.base, self.options, self.clock,
                                           measured=True)
                if motion is None:
                    raise StateConflict("replan", f"{v.id} is in the air off the plan and its "
                                                  f"position is unknown: nothing can be "
                                                  f"planned around it")
                self.flown.motions[v.id] = motion
            out.append(v)
        return out

    def predict_landing(self, v: VehicleStatus, kind: str) -> bool:
        """A faulty vehicle (policy replan) lands on its own: its predicted motion becomes
        its motion off the plans, and it is streamed that motion from now on (it follows
        it while it still listens), until PX4's Land takes it. From its last setpoint (what
        it was told), or where it is measured after a tracking error (it is not where it
        was told to be) or a lost link (from its last report, on its own failsafe). False
        when neither is known."""
        streamer = self.streamer
        assignment = streamer.assignments.get(v.id)
        last = assignment.last if assignment is not None else None
        measured = kind in ("tracking_error", "link_lost")
        motion = predicted_landing(v, self.base, self.options, self.clock, measured=measured,
                                   setpoint=last, setpoint_tick=streamer.tick,
                                   unheard=kind == "link_lost")
        if motion is None and not measured:
            motion = predicted_landing(v, self.base, self.options, self.clock, measured=True)
        if motion is None:
            return False
        self.flown.motions[v.id] = motion
        stream_motion(streamer, self.clock, v, motion, self.options.yaw)
        return True

    # ------------------------------------------------------------------ planning

    def _planned(self, record: ReplanRecord, fut: asyncio.Future[Replan], began: float
                 ) -> None:
        """The planning thread ended (in time or not): its planning time, as the flight
        saw it (what the next lead must cover)."""
        seconds = time.perf_counter() - began
        record.planning_s = round(seconds, 4)
        if not fut.cancelled() and fut.exception() is None:
            self._last_planning = seconds

    async def _run(self, job: Job, thread: asyncio.Future[Replan]) -> None:
        streamer = self.streamer
        switch_at = streamer.tick_time(job.tick)
        wait = switch_at - SWITCH_MARGIN_TICKS / streamer.rate - time.monotonic()
        await asyncio.wait({thread}, timeout=max(0.0, wait))
        if self.job is not job:
            return  # called off meanwhile
        if not thread.done():
            self._miss(job, f"no verified plan within the {job.record.lead_s:g} s lead "
                            f"(still planning)")
            return
        error = thread.exception()
        if isinstance(error, ReplanError):
            self._miss(job, str(error))
            return
        if error is not None:
            self._miss(job, f"planning failed: {type(error).__name__}: {error}")
            return
        result = thread.result()
        if not result.plan.ok:
            self._miss(job, f"the plan is not verified: {'; '.join(result.plan.problems())}")
            return
        if time.monotonic() > switch_at - 0.5 / streamer.rate or streamer.tick >= job.tick:
            self._miss(job, f"the plan came after its switch tick (planned in "
                            f"{result.seconds:.2f} s)")
            return
        changed = [v.id for v in job.steer + job.drop if not self.steered(v)]
        if changed:
            self._miss(job, f"{', '.join(changed)} left the plan meanwhile")
            return
        job.result = result
        self._queue(job)
        while streamer.tick < job.tick:
            await asyncio.sleep(max(POLL_S, streamer.tick_time(job.tick) - time.monotonic()))
            if self.job is not job:
                return  # called off before its tick
            if time.monotonic() > switch_at + STREAM_GONE_S and streamer.tick < job.tick:
                self._miss(job, "the stream stopped before the switch tick")
                return
        self._commit(job)

    def _queue(self, job: Job) -> None:
        """Queue every vehicle's new track at the switch tick."""
        assert job.result is not None
        streamer = self.streamer
        rate = streamer.rate
        plan = job.result.plan
        tails = plan_tracks(plan, [v.placed for v in job.steer], rate, self.options.yaw,
                            extra_s=self.options.hold_at_goal)
        for v, tail in zip(job.steer, tails, strict=True):
            job.tracks[v.id] = spliced(self.tracks[v.index], job.plan_tick, tail)
        for v in job.drop:
            tail = motion_track(job.drops[v.id], v.placed, rate, self.options.yaw)
            job.tracks[v.id] = spliced(self.tracks[v.index], job.plan_tick, tail)
        for v in job.steer + job.drop:
            streamer.switch(v.id, streamer.assignments[v.id].link, job.tracks[v.id], job.tick,
                            origin=self.clock.start_tick)
            job.switches.append(v.id)

    def _commit(self, job: Job) -> None:
        """The switch tick has come: the new plan is the flight's."""
        assert job.result is not None
        self.job = None
        result = job.result
        plan = result.plan
        t_switch = job.plan_tick / self.streamer.rate
        for v in job.steer + job.drop:
            self.tracks[v.index] = job.tracks[v.id]
        self.flown.switch(t_switch, plan)
        for v, goal in zip(job.steer, job.goals, strict=True):
            self.goals[v.id] = goal
            v.goal_ned = frames.world_to_ned(goal, v.placed)
            if v.phase == VehiclePhase.HOLDING:
                v.phase = VehiclePhase.FLYING  # back on its way
        for v in job.drop:
            self.flown.motions[v.id] = job.drops[v.id]
            v.dropped, v.drop_reason = job.action, job.record.reason
            if job.action == "land":
                v.phase = VehiclePhase.LANDING
                self.landings.append(self.tasks.spawn(
                    self._hand_over(v, job.drops[v.id].end)))
            else:
                v.phase = VehiclePhase.HOLDING
        for v in job.faulty:
            v.dropped, v.drop_reason = "land", f"fault {v.fault}"
        verification = plan.verification
        job.record.switched(Switch(
            horizon=round(plan.scenario.horizon, 3),
            request_to_switch_s=round(self.clock.tick_time(job.tick) + self.clock.t0
                                      - job.requested, 3),
            min_separation_planned=None if verification is None
            else verification.min_separation_continuous,
            separation_kept=round(result.separation, 4)))
        self.flown_plans[job.record.id] = {
            "plan": plan.to_dict(),
            "switch_gcs": self.clock.tick_time(job.tick),
        }
        self.emit(None, EventKind.REPLAN_SWITCHED, (
            f"replan {job.record.id}: {len(job.steer)} vehicle(s) on a verified plan from "
            f"t={t_switch:.2f} s (tick {job.tick}), {plan.scenario.horizon:.1f} s to the "
            f"goals, planned in {result.seconds:.3f} s"
            + (f"; {', '.join(v.id for v in job.drop)} {job.action} on their own motion"
               if job.drop else "")))
        self.on_switch()

    def _miss(self, job: Job, why: str, *, fallback: bool = True) -> None:
        """Not flown: the fleet goes on with its plan."""
        if self.job is job:
            self.job = None
        for vid in job.switches:
            self.streamer.cancel_switch(vid)
        job.record.missed(why)
        self.emit(None, EventKind.REPLAN_MISSED, f"replan {job.record.id}: {why}; the "
                                                 f"flight goes on with its plan")
        if job.faulty and fallback:
            self.on_missed(job.faulty, why)

    def cancel(self, why: str, *, fallback: bool = True) -> None:
        """Call off the replan under way (a fault, a pause, an abort came first); one
        whose switch tick has already come is the flight's plan now. `fallback` false: its
        faulty vehicles are not handed to `on_missed` (a new replan takes them on)."""
        job = self.job
        if job is None:
            return
        if job.result is not None and self.streamer.tick >= job.tick:
            self._commit(job)
            return
        self._miss(job, why, fallback=fallback)

    async def _hand_over(self, v: VehicleStatus, end: float) -> None:
        """Once a dropped vehicle's streamed descent has ended (flight time), PX4's Land."""
        while True:
            now = self.clock.flight_time()
            if now is not None and now >= end + SETTLE_S:
                break
            await asyncio.sleep(POLL_S * 5)
        if (self.active() and v.phase == VehiclePhase.LANDING and v.fault is None
                and v.id in self.streamer.assignments):
            await self.land(v)


def _state(v: VehicleStatus) -> str:
    if v.dropped is not None:
        return f"dropped: {v.dropped}"
    if v.fault is not None:
        return f"fault {v.fault}"
    return f"phase {v.phase}"


def _started_text(record: ReplanRecord) -> str:
    parts = [f"replan {record.id} ({record.reason or 'no reason given'}): switch at "
             f"t={record.switch_time:.2f} s ({record.lead_s:g} s lead)",
             f"{len(record.vehicles)} vehicle(s) planned"]
    if record.goals:
        parts.append("new goals for " + ", ".join(record.goals))
    if record.drop:
        parts.append(f"dropping {', '.join(record.drop)} ({record.drop_action})")
    if record.fixed:
        parts.append(f"around {', '.join(record.fixed)}")
    return "; ".join(parts)
