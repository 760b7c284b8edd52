"""Where a vehicle off the plans goes, predicted: a faulty vehicle PX4 lands, a lost one on
its own failsafe (`predicted_landing`, on the position controller's cascade), with the margins
the others keep from it; and a known motion streamed to a vehicle as setpoints
(`stream_motion`). The replans, the planned landing and the executor's checks of a faulty
vehicle's descent use the same predictions.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gcs import frames
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.setpoints import SetpointTrack
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.flight.replan.cascade import follow, substeps
from gcs.flight.timeline.clock import FlightClock
from gcs.flight.timeline.flown import Motion
from gcs.flight.timeline.stream import Streamer
from planner.model.fixed import FixedTrajectory, landing_motion
from planner.model.scenario import Scenario
from planner.types import FloatArray

__all__ = ["BRAKING_DECELERATION", "FAULT_MARGIN", "UNHEARD_GROWTH", "UNHEARD_MARGIN",
           "braking_deceleration", "hardest_braking", "motion_track", "predicted_landing",
           "stream_motion", "unheard_margin"]

#: Deceleration (m/s^2) of the predicted and streamed stops (at most the scenario's bound).
BRAKING_DECELERATION = 2.0
#: Extra distance (m) the others keep from a vehicle whose motion is predicted, not streamed
#: (a faulty one PX4 lands): its stop, descent speed and tracking are not the GCS's.
FAULT_MARGIN = 0.5
#: Extra distance (m) the others keep from a lost vehicle predicted on its own failsafe
#: from its last report (`predicted_landing`), which grows by `UNHEARD_GROWTH` per second
#: since it was last heard: its prediction starts from a report that ages, and nothing it
#: does is seen. (On the ideal mock the prediction ends within 0.1 m of where it lands.)
UNHEARD_MARGIN = 0.2
UNHEARD_GROWTH = 0.05
#: How long (s) a lost vehicle's failsafe hold takes to bring it to rest (the cascade's
#: overshoot has died down to millimetres by then).
SETTLE_HOLD_S = 3.0


def stream_motion(streamer: Streamer, clock: FlightClock, v: VehicleStatus, motion: Motion,
                  yaw_world: float) -> None:
    """From now on `v` is streamed `motion` (at its flight times), in case it still
    listens; nothing when it is not streamed."""
    assignment = streamer.assignments.get(v.id)
    if assignment is not None:
        streamer.assign(v.id, assignment.link, motion_track(
            motion, v.placed, streamer.rate, yaw_world),
            clock.start_tick + round(motion.start * streamer.rate))


def motion_track(motion: Motion, home: FloatArray, rate: float, yaw_world: float
                 ) -> SetpointTrack:
    """A known motion as setpoints from its start (tick 0), in the vehicle's LOCAL_NED."""
    count = math.floor((len(motion.trajectory) - 1) * motion.dt * rate + 1e-9) + 2
    p, v, a = motion.trajectory.state(np.arange(count) / rate, motion.dt)
    return SetpointTrack(frames.world_to_ned(p, home), frames.world_vector_to_ned(v),
                         frames.world_vector_to_ned(a), frames.world_yaw_to_ned(yaw_world),
                         rate)


def predicted_landing(v: VehicleStatus, base: Scenario, options: FlightOptions,
                      clock: FlightClock, *, measured: bool, setpoint: Any = None,
                      setpoint_tick: int | None = None, unheard: bool = False
                      ) -> Motion | None:
    """What a faulty vehicle PX4 lands does, predicted with `FAULT_MARGIN`: it stops, then
    descends at `land_speed` to the ground, from its last measured state (`measured`) or
    from its last setpoint (`setpoint`, sent at streamer tick `setpoint_tick`: what it was
    told, when its reports cannot be trusted). None when neither is known.

    unheard: the station has lost it (no reports, and no command may reach it): it follows
    its own offboard-loss failsafe (`v.failsafe`: on for `loss_timeout` at the velocity it
    had, then it brakes and holds in Position until its action, then lands straight down, or
    stays there for a Hold), and the margin grows by `UNHEARD_GROWTH` per second since it
    was last heard (`unheard_margin`)."""
    rate = clock.rate
    if v.home is None or clock.start is None:
        return None
    tel = v.link.telemetry if v.link is not None else None
    if measured and tel is not None and tel.position_ned is not None \
            and tel.position_time is not None:
        position = frames.ned_to_world(tel.position_ned, v.home)
        velocity = frames.ned_vector_to_world(tel.velocity_ned or (0.0, 0.0, 0.0))
        at = (tel.position_time - clock.t0 - clock.start - clock.paused_total)
    elif setpoint is not None and setpoint_tick is not None:
        position = frames.ned_to_world(setpoint.position, v.home)
        velocity = frames.ned_vector_to_world(setpoint.velocity)
        at = (setpoint_tick - clock.start_tick) / rate
    else:
        return None
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(velocity))):
        return None
    deceleration = braking_deceleration(base)
    ground = max(float(base.limits.position_min[2]), float(v.home[2]))
    floor = min(ground, float(position[2]))
    if not unheard:
        trajectory = landing_motion(v.id, position, velocity, base.dt, deceleration,
                                    options.land_speed, floor, margin=FAULT_MARGIN)
        return Motion(at, trajectory, base.dt, False)
    failsafe = v.failsafe
    dt = base.dt
    # until its failsafe it flies on on its last setpoint (about its last report), then it
    # holds where the failsafe found it, overshooting a little on the way (`cascade`)
    n = substeps(dt)
    on = math.ceil(failsafe.loss_timeout / dt - 1e-9) * n
    on_p, on_v = follow(position, velocity, position, velocity, on, dt / n)
    land = failsafe.effective != "Hold"
    settling = min(SETTLE_HOLD_S, failsafe.action_delay) if land else SETTLE_HOLD_S
    settle = math.ceil(settling / dt - 1e-9) * n
    hold_p, hold_v = follow(on_p[-1], on_v[-1], on_p[-1], 0.0, settle, dt / n)
    p = np.concatenate([on_p[:-1:n], hold_p[::n]])
    u = np.concatenate([on_v[:-1:n], hold_v[::n]])
    u[-1] = 0.0  # at rest on its hold: the rest of its motion starts from there
    margin = unheard_margin(max(0.0, (clock.flight_time() or at) - at))
    if not land:
        trajectory = FixedTrajectory(v.id, p, u, margin)
    else:
        then = landing_motion(v.id, p[-1], u[-1], dt, deceleration, options.land_speed,
                              floor, hold_s=max(0.0, failsafe.action_delay - settling))
        assert then.velocities is not None
        trajectory = FixedTrajectory(v.id, np.concatenate([p[:-1], then.positions]),
                                     np.concatenate([u[:-1], then.velocities]), margin)
    return Motion(at, trajectory, dt, False)


def braking_deceleration(base: Scenario) -> float:
    """The deceleration of the predicted and streamed stops (m/s^2): `BRAKING_DECELERATION`,
    at most the scenario's horizontal acceleration bound."""
    return min(BRAKING_DECELERATION, hardest_braking(base))


def hardest_braking(base: Scenario) -> float:
    """The hardest horizontal braking the scenario allows (m/s^2; `BRAKING_DECELERATION`
    when it has no acceleration bound)."""
    lim = base.limits.acceleration_max
    return BRAKING_DECELERATION if lim is None else float(np.min(lim[:2]))


def unheard_margin(age: float) -> float:
    """What the others keep beyond R from a vehicle last heard `age` s ago (m)."""
    return UNHEARD_MARGIN + UNHEARD_GROWTH * age
