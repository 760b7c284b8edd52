"""Flying a landing plan: the planned, checked way down when a flight is stopped with `land`.

An abort with `land` (operator, Ctrl-C, the service stopping, a fault policy) does not send
every vehicle straight down with PX4's Land where it is, which can bring two vehicles
stacked above each other closer than R. `PlannedLanding.run`:

1. picks a switch tick `landing_plan_timeout` ahead, and every steerable vehicle's state at
   that tick: the setpoint its stream would send then (the plan's exact state, or its pause
   hold), converted to the world frame; a vehicle with a tracking error is planned from
   where it is measured;
2. plans the landing (`planner.methods.landing.plan_landing`, verified) in a worker thread while
   the streams go on along the flying plan, which keeps R until the switch;
3. at the switch tick streams the landing plan as setpoints, like a plan (queued with
   `Streamer.switch`, so every setpoint before it is still the flying plan's); once the landing
   horizon has passed, every vehicle stands at its touchdown point `landing_height` above
   the workspace floor, and PX4's Land takes it down vertically (touchdown points are R
   apart, so no descent crosses another vehicle).

Vehicles that cannot be steered (link or heartbeat lost, out of OFFBOARD, estimate invalid,
already landing) are moving obstacles the landing plan keeps R + a margin from
(`planner.model.fixed`, given to `plan_landing` from the switch on, with the `around` vehicles
another part of the flight lands): one still heard gets PX4's Land at once and is predicted
going straight down from where it is measured; one the station has lost is predicted on its own
offboard-loss failsafe from its last report (`gcs.flight.replan.prediction.predicted_landing`,
its margin growing with the time since it was heard), is streamed that motion in case it still
listens, and gets PX4's Land only once the motion has ended (a Land arriving earlier would take
it down before its predicted hold was over). Their motions go to `FlownPlans.motions`, where
the live separation monitor reads where a lost vehicle is predicted. A steered vehicle already
nearer than R to one of them keeps what it has from that one alone, back to R within seconds
(`planner.methods.landing.fixed_start_clearances`). Where no landing plan keeps R from them (at
any share of the margin, `MARGIN_SHARES`), a verified plan first moves the steered vehicles
away from their columns, and the landing is planned again from there (at most `MAX_ESCAPES`
times). Everyone gets PX4's Land when no verified plan is ready before the switch tick (the
planner failed for whatever reason, or was late): the events say which (`landing_plan`,
`landing_fallback`). Whatever happens, every vehicle is handed to `secure` in the end.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field, replace

import numpy as np

from gcs import frames
from gcs.flight.link.setpoints import plan_tracks
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.prediction import predicted_landing, stream_motion
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import FlownPlans, Motion, shifted
from gcs.flight.timeline.stream import Streamer
from gcs.phases import AIRBORNE, EventKind, VehiclePhase
from planner.methods.landing import STAGES, LandingError, LandingPlan, plan_landing
from planner.model.fixed import CLEARANCE_RAMP_S, FixedTrajectory
from planner.model.scenario import Scenario
from planner.types import FloatArray

__all__ = ["STEERABLE_FAULTS", "PlannedLanding"]

#: Faults after which a vehicle still follows setpoints (it can fly a landing plan, from
#: where it is measured).
STEERABLE_FAULTS = ("tracking_error",)
#: Vehicle phases in which a vehicle flies the plan (or holds on it) and can be re-planned.
FLYING_PHASES = (VehiclePhase.FLYING, VehiclePhase.HOLDING, VehiclePhase.FAULTY)
#: Ticks kept free between the plan being ready and its switch tick (to build the tracks).
SWITCH_MARGIN_TICKS = 1
#: Shares of the margins around the vehicles it cannot steer a landing plan is tried with,
#: in turn, while none is found (a lost vehicle caught at R from another leaves no room to
#: open the full margin at once).
MARGIN_SHARES = (1.0, 0.5, 0.0)
#: While a lost vehicle comes down on its own and no landing plan was found, the others hold
#: and a landing is planned again this often (s), from the held state.
RETRY_S = 0.5
#: After the landing horizon, PX4's Land takes over once the vehicles had this long to settle.
SETTLE_S = 0.3
#: Plans that move the vehicles away from a lost vehicle's column (no landing kept clear of
#: it) flown at most before a landing; from their ends a vehicle can go straight down, so
#: the landing after one rarely fails.
MAX_ESCAPES = 2


@dataclass
class PlannedLanding:
    """One landing of a fleet by a landing plan (see the module)."""

    scenario: Scenario
    """The flying plan's scenario: workspace, boxes, R, step length."""
    vehicles: list[VehicleStatus]
    streamer: Streamer
    context: FlightContext
    """The flight it lands (`gcs.flight.procedure.context`): options, events, stalls."""
    secure: Callable[[VehicleStatus], Awaitable[None]]
    """Leaves one vehicle safe with PX4's Land (`gcs.flight.procedure.endings.secure`: disarmed on
    the ground, or landing); its stream stops."""
    flown: FlownPlans | None = None
    """The flight's plans and motions off them (None: nothing is predicted)."""
    clock: FlightClock | None = None
    around: list[VehicleStatus] = field(default_factory=list)
    """Vehicles in the air that others land (not handed to `secure` here), planned around."""
    steered: list[VehicleStatus] = field(default_factory=list)
    """The vehicles flying the landing plan (once switched)."""
    result: LandingPlan | None = None
    predicted: dict[str, Motion] = field(default_factory=dict)
    """The predicted motions of the vehicles it cannot steer, by id."""
    unheard: set[str] = field(default_factory=set)
    """Those of them the station has lost (on their own failsafe)."""
    escapes: int = 0
    """Plans flown that moved the vehicles away from a column instead of landing them."""

    def steerable(self, v: VehicleStatus) -> str | None:
        """Why `v` cannot fly a landing plan, or None when it can."""
        if v.link is None or v.home is None:
            return "not connected"
        if v.fault is not None and v.fault not in STEERABLE_FAULTS:
            return f"fault {v.fault}"
        if v.phase not in FLYING_PHASES:
            return f"phase {v.phase}"
        if v.id not in self.streamer.assignments:
            return "not streaming"
        age = self.context.stalls.age(v.link.telemetry.message_time, time.monotonic())
        if not age <= self.context.options.link_timeout:
            return "link silent"
        return None

    def _state(self, v: VehicleStatus, tick: int, at: float) -> tuple[FloatArray, ...]:
        """(position, velocity, acceleration) in the world frame of `v` at `tick` (GCS
        instant `at`): its stream's setpoint then, or (a faulty one) where it is measured."""
        home = v.placed
        tel = v.linked.telemetry
        if v.fault is not None and tel.position_ned is not None \
                and tel.position_time is not None:
            velocity = np.asarray(tel.velocity_ned or (0.0, 0.0, 0.0), dtype=float)
            position = np.asarray(tel.position_ned) + velocity * (at - tel.position_time)
            return (frames.ned_to_world(position, home), frames.ned_vector_to_world(velocity),
                    np.zeros(3))
        assignment = self.streamer.assignments[v.id]
        sp = assignment.track.at(tick - assignment.start_tick)
        return (frames.ned_to_world(sp.position, home), frames.ned_vector_to_world(sp.velocity),
                frames.ned_vector_to_world(sp.acceleration))

    def eligible(self) -> list[VehicleStatus]:
        """The vehicles a landing plan can steer (the others get PX4's Land)."""
        return [v for v in self.vehicles if self.steerable(v) is None]

    async def run(self) -> None:
        """Land every vehicle: the steerable ones by a landing plan if one is ready in time,
        the rest (or all, when none is) by PX4's Land. Never raises; whatever happens (even
        cancellation), every vehicle is handed to `secure` once."""
        streamer = self.streamer
        rate = streamer.rate
        downs: list[asyncio.Future[None]] = []
        handed: set[str] = set()

        def down(v: VehicleStatus) -> None:
            handed.add(v.id)
            downs.append(asyncio.ensure_future(self.secure(v)))

        try:
            steer = self.eligible()
            for v in self.vehicles:
                if v in steer:
                    continue
                airborne = v.phase in AIRBORNE and v.phase != VehiclePhase.LANDING
                if v.phase in AIRBORNE and self._lost(v):
                    self.context.emit(v.id, EventKind.LANDING_FALLBACK, (
                        f"lost ({self.steerable(v)}): on its own failsafe "
                        f"({v.failsafe.text()}), planned around"))
                    self._predict(v, unheard=True)
                    continue  # handed to `secure` once its predicted motion has ended
                if airborne:
                    self.context.emit(v.id, EventKind.LANDING_FALLBACK,
                                      f"PX4 Land: cannot be steered ({self.steerable(v)})")
                down(v)
                self._predict(v, unheard=False)
            if steer:
                ok = await self._fly(steer, rate)
                for v in (self.steered if ok else steer):
                    down(v)
                handed.update(v.id for v in steer)  # the rest were sent down meanwhile
            for v in self.vehicles:
                if v.id not in handed and v.id in self.predicted:
                    await self._until_flight_time(self.predicted[v.id].end + SETTLE_S)
                    down(v)
        finally:
            for v in self.vehicles:
                if v.id not in handed:
                    down(v)
            await asyncio.gather(*downs, return_exceptions=True)

    def _lost(self, v: VehicleStatus) -> bool:
        """True when the station has lost `v`: no report for `link_timeout`."""
        if v.link is None or v.home is None:
            return False
        age = self.context.stalls.age(v.link.telemetry.position_time, time.monotonic())
        return v.fault == "link_lost" or not age <= self.context.options.link_timeout

    def _predict(self, v: VehicleStatus, *, unheard: bool) -> None:
        """Predict what `v`, which the landing plan cannot steer, does: its known motion off
        the plans, or PX4's Land from where it is measured, or (`unheard`) its own failsafe
        from its last report, then streamed to it. Kept in `flown.motions`."""
        if self.flown is None or self.clock is None or v.phase not in AIRBORNE:
            return
        motion = self.flown.motions.get(v.id) if not unheard else None
        if motion is None:
            motion = predicted_landing(v, self.scenario, self.context.options, self.clock,
                                       measured=True, unheard=unheard)
        if motion is None:
            return
        self.flown.motions[v.id] = motion
        self.predicted[v.id] = motion
        if unheard:
            self.unheard.add(v.id)
            stream_motion(self.streamer, self.clock, v, motion, self.context.options.yaw)

    def _fixed(self, switch: int) -> list[FixedTrajectory]:
        """The motions of the vehicles the plan cannot steer, from streamer tick `switch`."""
        if self.flown is None or self.clock is None or self.clock.start is None:
            return []
        t_switch = (switch - self.clock.start_tick) / self.streamer.rate
        for v in self.around:
            if v.phase in AIRBORNE and v.id not in self.predicted:
                self._predict(v, unheard=self._lost(v))
        return [shifted(m, t_switch) for m in self.predicted.values()]

    async def _until_flight_time(self, t: float) -> None:
        """Sleep until flight time `t` (at once without a running flight clock)."""
        while self.clock is not None and (now := self.clock.flight_time()) is not None \
                and now < t:
            await asyncio.sleep(min(0.1, t - now))

    async def _fly(self, steer: list[VehicleStatus], rate: float) -> bool:
        """Plan, switch, fly the landing plan; False (after freezing the streams) when no
        plan was ready in time, which the events say. While a lost vehicle is still coming
        down on its own, a failed attempt freezes the streams (the others hold where they
        are, rather than go straight down across its column) and is tried again every
        `RETRY_S` from the held state, and once more after it is down."""
        why = await self._attempt(steer, rate)
        if why is not None and self._lost_in_air():
            self._freeze(steer)
            self.context.emit(None, EventKind.LANDING_FALLBACK, (
                f"{', '.join(v.id for v in steer)} hold where they are: {why}; landing "
                f"planned again every {RETRY_S:g} s around {', '.join(sorted(self.unheard))}"))
            while why is not None:
                last = not self._lost_in_air()  # one more try once it is down
                await asyncio.sleep(RETRY_S)
                why = await self._attempt(steer, rate)
                if last:
                    break
        return True if why is None else self._fallback(steer, why)

    def _lost_in_air(self) -> bool:
        """True while a lost vehicle (`predicted`, unheard) is predicted in the air."""
        now = self.clock.flight_time() if self.clock is not None else None
        return now is not None and any(
            vid in self.unheard and now < motion.end + SETTLE_S
            for vid, motion in self.predicted.items())

    async def _attempt(self, steer: list[VehicleStatus], rate: float) -> str | None:
        """One landing plan from the state `landing_plan_timeout` ahead: None once it was
        flown to its end, or why there was none."""
        streamer = self.streamer
        options = self.context.options
        bound = options.landing_plan_timeout
        switch = streamer.next_tick() + SWITCH_MARGIN_TICKS + math.ceil(bound * rate)
        switch_at = streamer.tick_time(switch)
        states = [self._state(v, switch, switch_at) for v in steer]
        fixed = self._fixed(switch)
        positions, velocities, accelerations = (np.array([s[k] for s in states])
                                                for k in range(3))
        began = time.perf_counter()
        deadline = began + bound
        def planned() -> LandingPlan:
            """The landing plan, keeping the full margins from the vehicles it cannot steer
            or, when no plan can, a share of them (`MARGIN_SHARES`); when none keeps even R
            from them, a plan that moves the vehicles away from their columns first."""
            tries = [(stage, share) for stage in STAGES for share in MARGIN_SHARES]
            for n, (stage, share) in enumerate(tries, start=1):
                try:
                    return plan_landing(
                        self.scenario, positions, velocities, accelerations,
                        ids=[v.id for v in steer], landing_height=options.landing_height,
                        deadline=deadline, fixed=[replace(f, margin=share * f.margin)
                                                  for f in fixed], stages=(stage,))
                except LandingError:
                    if n == len(tries) or not fixed or time.perf_counter() > deadline:
                        raise
            raise AssertionError("unreachable")

        try:
            result = await asyncio.wait_for(asyncio.to_thread(planned), timeout=max(
                0.0, switch_at - time.monotonic() - SWITCH_MARGIN_TICKS / rate))
        except TimeoutError:
            return f"no landing plan within {bound:g} s"
        except LandingError as exc:
            return str(exc)
        except Exception as exc:  # any planning failure: PX4 Land, never stuck
            return f"landing planning failed: {type(exc).__name__}: {exc}"
        if time.monotonic() > switch_at - 0.5 / rate or streamer.tick >= switch:
            return (f"the landing plan came after its switch tick "
                    f"({time.perf_counter() - began:.2f} s)")
        self.result = result
        self._switch(steer, result, switch, rate)
        self._announce(result, bound)
        end = switch_at + result.plan.scenario.horizon + SETTLE_S
        while (left := end - time.monotonic()) > 0:
            await asyncio.sleep(left)
        if result.touchdown:
            return None
        # it moved them away from the columns of the vehicles it cannot steer: land from there
        self.escapes += 1
        if self.escapes > MAX_ESCAPES:
            return f"no landing plan after moving away {MAX_ESCAPES} time(s)"
        return await self._attempt([v for v in steer if v in self.steered], rate)

    def _switch(self, steer: list[VehicleStatus], result: LandingPlan, switch: int,
                rate: float) -> None:
        """Queue `result`'s tracks for the streams of `steer` at tick `switch`."""
        streamer = self.streamer
        homes = [v.placed for v in steer]
        tracks = plan_tracks(result.plan, homes, rate, self.context.options.yaw)
        for v, track in zip(steer, tracks, strict=True):
            link = streamer.assignments[v.id].link if v.id in streamer.assignments else None
            if link is None:
                continue  # sent down meanwhile (a fault policy)
            streamer.switch(v.id, link, track, switch)  # the flying plan streams until then
            v.phase = VehiclePhase.LANDING
            if v not in self.steered:
                self.steered.append(v)

    def _announce(self, result: LandingPlan, bound: float) -> None:
        """The `landing_plan` event of a plan about to be flown: what it keeps, from whom."""
        horizon = result.plan.scenario.horizon
        verification = result.plan.verification
        kept = verification.min_separation_continuous if verification is not None else None
        kept_from = result.plan.scenario.fixed
        around = (f"; around {', '.join(f.id for f in kept_from)} (closest "
                  f"{_figure(_fixed_kept(result))} m, margin "
                  f"{', '.join(f'{f.margin:.2f}' for f in kept_from)} m beyond R)"
                  if kept_from else "")
        what = (f"land by a verified plan from t+{bound:g} s: touchdown in {horizon:.1f} s"
                if result.touchdown else
                f"move away first by a verified plan from t+{bound:g} s (no landing keeps "
                f"clear of {', '.join(f.id for f in kept_from)}): clear of their columns in "
                f"{horizon:.1f} s, then land from there")
        relaxed = [f"{vid} from {f.id}" for f in kept_from for vid in f.start_clearance]
        self.context.emit(None, EventKind.LANDING_PLAN, (
            f"{len(self.steered)} vehicle(s) {what}, closest {_figure(kept)} m (keeps at "
            f"least {result.separation:.2f} m), planned in {result.seconds:.3f} s{around}"
            + (f"; started nearer than R: {', '.join(relaxed)} (those pairs back to R "
               f"within {CLEARANCE_RAMP_S:g} s)" if relaxed else "")))

    def _freeze(self, steer: list[VehicleStatus]) -> None:
        """Every stream of `steer` holds its last setpoint from now on (the vehicles are
        landing: no longer judged against the plan)."""
        for v in steer:
            v.phase = VehiclePhase.LANDING
        self.streamer.freeze(v.id for v in steer)

    def _fallback(self, steer: list[VehicleStatus], why: str) -> bool:
        """Freeze the streams where they are and say that PX4's Land takes over."""
        self._freeze(steer)
        self.context.emit(None, EventKind.LANDING_FALLBACK,
                          f"PX4 Land for {', '.join(v.id for v in steer)}: {why}")
        return False


def _fixed_kept(result: LandingPlan) -> float | None:
    """The closest the landing plan comes to a vehicle it cannot steer (m)."""
    verification = result.plan.verification
    return None if verification is None else verification.fixed_distance_min


def _figure(x: float | None) -> str:
    return "?" if x is None else f"{x:.2f}"
