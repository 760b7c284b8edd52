"""Fault routing: what the monitor finds reaches the part of the flight that acts on it.

`FaultRouter` is the flight's side of the monitor (what it watches:
`gcs.flight.safety.monitor.Watched`) and what carries out the fault policy's decisions
(`gcs.flight.safety.policy.Responder`):

- a vehicle unheard for `SILENT_HOLD_S` pauses the flight on the plan time where the others
  keep the most room from where it stops on its own (`gcs.flight.safety.silence`); heard
  again, the flight resumes;
- a fault calls off a replan planned without knowing it (under policy replan the new one is),
  ends a silence's pause where the policy flies the others on, makes a lost vehicle's
  predicted motion an obstacle of every later plan and streams it, then the policy acts
  (`gcs.flight.safety.policy`);
- policy replan lands the faulty vehicle on its own and replans the others around it
  (`gcs.flight.replan.replan`), or goes land_faulty's way when it cannot;
- a separation alarm goes to the policy.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable, Sequence

import numpy as np

from gcs import frames
from gcs.errors import GcsError, StateConflict
from gcs.flight.procedure import endings
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.prediction import predicted_landing, stream_motion, unheard_margin
from gcs.flight.replan.replan import Replanner
from gcs.flight.run.state import RunningFlight
from gcs.flight.safety.descent import DescentConflict, descent_conflicts
from gcs.flight.safety.landing import SETTLE_S
from gcs.flight.safety.margin import required_separation
from gcs.flight.safety.monitor import PERIOD, FleetMonitor, Watched
from gcs.flight.safety.policy import FaultPolicy, Responder
from gcs.flight.safety.silence import silent_hold
from gcs.flight.timeline.clock import Pause
from gcs.phases import AIRBORNE, EventKind, FlightPhase

__all__ = ["FaultRouter"]


class FaultRouter(Watched, Responder):
    """The flight's answer to what its monitor finds (see the module)."""

    def __init__(self, flight: RunningFlight, now: Callable[[], float]) -> None:
        """`now`: the GCS clock (s), when a fault is noted."""
        self.flight = flight
        self.monitor = FleetMonitor(flight.vehicles, flight.plan, flight.context, self)
        """What finds the faults (`gcs.flight.safety.monitor`); `run` it while the flight
        lasts."""
        self.policy = FaultPolicy(flight.context, now, self)
        """What a fault or a separation alarm does (`gcs.flight.safety.policy`)."""
        self._silence_pause: Pause | None = None
        """The pause made because a vehicle fell silent (`on_silent`); it is over once the
        clock holds another pause or none."""

    # ------------------------------------------------------------ what the monitor reads

    def flight_time(self) -> float | None:
        return self.flight.clock.flight_time()

    def planned(self, v: VehicleStatus, times: Sequence[float] | np.ndarray) -> np.ndarray:
        return self.flight.flown.position(v.id, times)

    def predicted(self, v: VehicleStatus, t: float) -> np.ndarray | None:
        return self.flight.flown.predicted(v.id, t)

    # ------------------------------------------------------------ what the monitor finds

    def on_silent(self, v: VehicleStatus, silent: float) -> None:
        """`v` has been unheard for `SILENT_HOLD_S`: stop the flight clock, so that the
        others stop on the plan where they keep the most room from where it stops on its
        own if its link is lost (it flies on to its last setpoint, then holds: its
        failsafe; `gcs.flight.safety.silence`)."""
        flight = self.flight
        if (flight.phase != FlightPhase.FLYING or flight.aborting is not None
                or flight.clock.pause is not None or flight.clock.start is None):
            return
        t = flight.pause(self._silent_hold(v))
        self._silence_pause = flight.clock.pause
        flight.context.emit(v.id, EventKind.LINK_SILENT,
                            f"no message for {silent:.2f} s: the fleet holds on the plan at "
                            f"t={t:.2f} s until it is heard again or declared lost")

    def on_heard(self, v: VehicleStatus) -> None:
        """A silent vehicle is heard again: resume when nothing else keeps the fleet held."""
        flight = self.flight
        if self._silenced() and not self.monitor.silent:
            self._silence_pause = None
            flight.context.emit(v.id, EventKind.LINK_SILENT, "heard again: the flight goes on")
            flight.resume()

    def on_fault(self, v: VehicleStatus, kind: str, detail: str) -> None:
        """The monitor flagged `v`: a replan planned without knowing it is called off (under
        policy replan the new one is), then the policy acts."""
        flight = self.flight
        options = flight.options
        if flight.replanner is not None and options.policy != "replan":
            flight.replanner.cancel(f"{v.id} faulted ({kind}) while it was planned")
        if self._silenced() and options.policy in ("land_faulty", "replan"):
            self._silence_pause = None  # these policies fly the others on
            flight.resume()
        if kind == "link_lost" and v.phase in AIRBORNE and v.home is not None:
            # a moving obstacle for every plan made from now on, and what the separation
            # monitor counts for it while it is unheard
            motion = predicted_landing(v, flight.plan.scenario.assigned(), options,
                                       flight.clock, measured=True, unheard=True)
            if motion is not None and flight.streamer is not None:
                flight.flown.motions[v.id] = motion
                stream_motion(flight.streamer, flight.clock, v, motion, options.yaw)
        self.policy.on_fault(v, kind, detail)

    def on_separation(self, closest: float, alarm: float, between: str) -> None:
        self.policy.on_separation(closest, alarm, between)

    # ------------------------------------------------------------ what the policy asks

    async def land(self, v: VehicleStatus) -> None:
        """Land for a faulty vehicle: at once, or for a lost one once its predicted
        failsafe motion has ended (a Land arriving earlier would take it down before the
        hold the others were planned around was over)."""
        motion = self.flight.flown.motions.get(v.id)
        if v.fault == "link_lost" and motion is not None:
            while ((now := self.flight.clock.flight_time()) is not None
                   and now < motion.end + SETTLE_S):
                await asyncio.sleep(min(PERIOD, motion.end + SETTLE_S - now))
        await endings.land_vehicle(v, self.flight.context)

    async def abort(self, action: str, reason: str) -> None:
        """A fault's abort: one that loses to an abort under way leaves only its
        `command_refused` event (nobody waits for an answer)."""
        with contextlib.suppress(StateConflict):
            await self.flight.abort(action, reason)

    def aborting(self) -> bool:
        return self.flight.aborting is not None

    def descent(self, v: VehicleStatus) -> list[DescentConflict] | None:
        """The others whose plan `v`'s straight descent from where it was last seen would
        come closer than R to (`gcs.flight.safety.descent`); None when that cannot be known
        (no position, or the plan's clock not started)."""
        flight = self.flight
        now = flight.clock.flight_time()
        tel = None if v.link is None else v.link.telemetry
        if now is None or v.home is None or tel is None or tel.position_ned is None:
            return None
        position = frames.ned_to_world(tel.position_ned, v.home)
        if not np.all(np.isfinite(position)):
            return None
        flying = flight.flown.current  # the plan in force: the first, or a switched replan's
        clearance = required_separation(flight.plan.scenario)
        hold = 0.0
        if v.fault == "link_lost":  # on its own failsafe: it holds first, seen from afar
            age = flight.context.stalls.age(tel.position_time, time.monotonic())
            # one that holds for good (ArduCopter without its GCS failsafe) is passed by the
            # others for the rest of the plan: its column counts for the whole plan
            hold = min(v.failsafe.hold_s, flying.plan.scenario.horizon)
            clearance += unheard_margin(age)
        return descent_conflicts(flying.plan, v.id, position, now - flying.start, clearance,
                                 ground=float(v.home[2]), hold=hold)

    def replan(self, v: VehicleStatus, kind: str) -> None:
        """Policy replan: `v` lands on its own (its Land; streamed its predicted motion
        meanwhile, in case it still listens) and the others replan around that motion; when
        they cannot, land_faulty's way (`FaultPolicy.give_way`)."""
        replanner: Replanner | None
        try:
            replanner = self.flight.replanner_now()
        except GcsError as exc:
            replanner, why = None, exc.reason if isinstance(exc, StateConflict) else str(exc)
        if replanner is not None and not replanner.predict_landing(v, kind):
            replanner, why = None, "its motion cannot be predicted (no position)"
        self.policy.landings.append(self.policy.tasks.spawn(self.land(v)))
        if replanner is None:
            self.replan_missed([v], why)
            return
        with contextlib.suppress(Exception):  # on failure it fell back (`replan_missed`)
            replanner.request(None, (), "land", f"{v.id} {kind}", faulty=[v])

    def replan_missed(self, faulty: list[VehicleStatus], why: str) -> None:
        """Policy replan could not fly the others around `faulty`: land_faulty's way."""
        for v in faulty:
            self.flight.context.emit(
                v.id, EventKind.REPLAN_MISSED,
                f"policy replan: no replan around it ({why}); land_faulty's way: the others "
                f"fly on only where its descent is clear")
            self.policy.give_way(v)

    # ------------------------------------------------------------ helpers

    def _silenced(self) -> bool:
        """True while the flight holds the pause a silence made (nobody resumed or aborted
        since)."""
        flight = self.flight
        return (self._silence_pause is not None and flight.clock.pause is self._silence_pause
                and flight.aborting is None)

    def _silent_hold(self, v: VehicleStatus) -> float | None:
        """The flight time whose plan setpoints the others hold while `v` is silent (None:
        the one reached)."""
        flight = self.flight
        now = flight.clock.flight_time()
        motion = predicted_landing(v, flight.plan.scenario, flight.options, flight.clock,
                                   measured=True, unheard=True)
        if now is None or motion is None or flight.streamer is None:
            return None
        held, positions, velocities = [], [], []
        for u in flight.vehicles:
            tel = u.link.telemetry if u.link is not None else None
            if (u.id == v.id or u.fault is not None or u.home is None or tel is None
                    or tel.position_ned is None):
                continue
            held.append(u.id)
            positions.append(frames.ned_to_world(tel.position_ned, u.home))
            velocities.append(frames.ned_vector_to_world(tel.velocity_ned or (0.0, 0.0, 0.0)))
        flying = flight.flown.current
        return flying.start + silent_hold(
            flying.plan, lambda s: motion.position(now + s), now - flying.start, held,
            np.array(positions).reshape(-1, 3), np.array(velocities).reshape(-1, 3),
            flight.streamer.rate)
