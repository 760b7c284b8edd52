"""The plans a flight flies, on its flight clock: the first from time 0, each switched
replan's from its switch time, and the known motions of vehicles off the plans.

A replan (`gcs.flight.replan.replan`) changes what each vehicle is meant to do from its switch
time on; what the monitor checks the tracking against, what the record's tracking error is
measured against and when the flight's plan ends all follow from here. A vehicle a replan
dropped, or one that faulted and lands on its own, follows a `FixedTrajectory` (its
predicted motion) from the flight time it was made for.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from planner import Plan
from planner.model.fixed import FixedTrajectory
from planner.types import FloatArray

__all__ = ["FlownPlans", "Motion", "Segment", "shifted"]


@dataclass(frozen=True)
class Segment:
    """One plan of the flight, flown from flight time `start` (its time 0)."""

    start: float
    plan: Plan
    index: dict[str, int]
    """Plan vehicle index by vehicle id."""


@dataclass(frozen=True)
class Motion:
    """A vehicle's known motion off the plans, from flight time `start` (its time 0)."""

    start: float
    trajectory: FixedTrajectory
    dt: float
    """The sample spacing of `trajectory` (s)."""
    streamed: bool
    """True when the GCS streams it (a dropped vehicle), False when it is a prediction of
    what the vehicle does on its own (a faulty one PX4 lands)."""

    def position(self, t: ArrayLike) -> FloatArray:
        """World positions at flight times `t` (T, 3)."""
        return self.trajectory.state(np.asarray(t, dtype=float) - self.start, self.dt)[0]

    @property
    def end(self) -> float:
        """Flight time at which it comes to rest."""
        return self.start + (len(self.trajectory) - 1) * self.dt


def shifted(motion: Motion, start: float) -> FixedTrajectory:
    """`motion` from flight time `start` on, on its own grid (what a replan switching at
    `start` is given as fixed); at rest at its last sample once it has ended."""
    offset = max(0.0, start - motion.start)
    traj = motion.trajectory
    left = (len(traj) - 1) * motion.dt - offset
    count = max(1, math.floor(left / motion.dt + 1e-9) + 1) if left > 0 else 1
    times = offset + np.arange(count) * motion.dt
    position, velocity, _ = traj.state(times, motion.dt)
    if left > 0 and times[-1] < offset + left - 1e-9:  # end exactly at rest
        last, _, _ = traj.state([offset + left + motion.dt], motion.dt)
        position = np.vstack([position, last])
        velocity = np.vstack([velocity, np.zeros((1, 3))])
    return FixedTrajectory(traj.id, position, velocity, traj.margin)


@dataclass
class FlownPlans:
    """Every plan of one flight in flight time, and the motions off them (see the module)."""

    segments: list[Segment]
    motions: dict[str, Motion] = field(default_factory=dict)
    """The latest known motion of each vehicle off the plans, by vehicle id."""

    @staticmethod
    def of(plan: Plan) -> FlownPlans:
        return FlownPlans([Segment(0.0, plan, _index(plan))])

    @property
    def current(self) -> Segment:
        return self.segments[-1]

    @property
    def horizon(self) -> float:
        """Flight time at which the current plan ends."""
        seg = self.current
        return seg.start + seg.plan.scenario.horizon

    def switch(self, start: float, plan: Plan) -> None:
        """From flight time `start`, the flight flies `plan`."""
        self.segments.append(Segment(start, plan, _index(plan)))

    def position(self, vehicle_id: str, times: Sequence[float] | FloatArray) -> FloatArray:
        """Where `vehicle_id` is meant to be at flight times `times` (T, 3), world frame:
        the plan in force then, or its motion off the plans from the motion's start; NaN
        where neither says."""
        t = np.asarray(times, dtype=float).reshape(-1)
        out = np.full((len(t), 3), np.nan)
        for n, seg in enumerate(self.segments):
            i = seg.index.get(vehicle_id)
            if n > 0:
                inside = t >= seg.start
                if not inside.any():
                    break
                out[inside] = np.nan  # this plan takes over: with or without the vehicle
            else:
                inside = np.ones(len(t), dtype=bool)
            if i is not None:
                sample = seg.plan.vehicles[i].sample(seg.plan.scenario.dt, t[inside] - seg.start)
                out[inside] = sample.position
        motion = self.motions.get(vehicle_id)
        if motion is not None:
            after = t >= motion.start
            if after.any():
                out[after] = motion.position(t[after])
        return out

    def predicted(self, vehicle_id: str, t: float) -> FloatArray | None:
        """Where `vehicle_id`'s motion off the plans puts it at flight time `t` (None when
        it has none, or not yet)."""
        motion = self.motions.get(vehicle_id)
        if motion is None or t < motion.start:
            return None
        position: FloatArray | None = motion.position([t])[0]
        return position

    def planned(self, vehicle_id: str, t: float) -> bool:
        """True when a plan steers `vehicle_id` at flight time `t` (not off the plans)."""
        motion = self.motions.get(vehicle_id)
        if motion is not None and t >= motion.start:
            return False
        seg = next((s for s in reversed(self.segments) if s.start <= t), self.segments[0])
        return vehicle_id in seg.index


def _index(plan: Plan) -> dict[str, int]:
    return {vid: i for i, vid in enumerate(plan.scenario.ids)}
