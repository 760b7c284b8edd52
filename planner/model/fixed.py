"""Fixed trajectories: vehicles whose motion is known and not planned.

Long: fixed trajectories: the dataclasses and the braking, landing and dropped motions.

A vehicle descending to land, braking to a hold, or flying on its own failsafe is not a
planned vehicle, yet the planned ones must keep R from it. A `FixedTrajectory` is such a
vehicle's motion on the scenario's step grid (world frame ENU): positions at t = k dt and,
optionally, velocities; inside step k the motion is the quadratic that leaves p_k with v_k
and reaches p_k+1 (straight at constant speed when no velocities are given), the same
piecewise-quadratic motion as a planned vehicle's, so every pair distance between a planned
and a fixed vehicle is exact between steps. After its last sample it rests there.

The planned vehicles keep R + `margin` from it over continuous time (`planner.scp.fixed_rows`
for the SCP rows, `planner.verification.verify` for the check): `margin` covers an uncertain
prediction. A planned vehicle that starts closer than R to it (a lost vehicle's neighbour
when the loss is noticed) is named in its `start_clearance`: that pair alone keeps what it
starts with over the first step, then a clearance growing back to R + the margin over
`CLEARANCE_RAMP_S`; every other pair keeps R + the margin.
`braking_motion` and `landing_motion` predict the motion of a vehicle told to hold or land;
one dropped from a flying plan first coasts `DROP_COAST_STEPS` on its state's acceleration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import ScenarioError
from planner.model.checks import RANGES, check_id, check_keys, check_list, check_number
from planner.types import FloatArray, IntArray

__all__ = ["CLEARANCE_RAMP_S", "DROP_COAST_STEPS", "MARGIN_RAMP_S", "MAX_FIXED", "FixedSet",
           "FixedTrajectory", "braking_motion", "check_fixed_clear", "dropped_motion",
           "landing_motion", "margin_at", "parse_fixed", "relief_at"]

#: At most this many fixed trajectories per scenario (a cap on work, not a physical limit).
MAX_FIXED = 256
#: A fixed vehicle's margin grows linearly from 0 after the first step to its full value
#: over this long (s): the prediction starts where the vehicle is, and drifts with time.
MARGIN_RAMP_S = 1.0
#: A pair in a fixed trajectory's `start_clearance` gets back to the full R + margin this
#: long (s) after the first step, linearly from what it starts with: long enough for a
#: vehicle to turn away from a neighbour it was closing in on, short enough that the pair is
#: relaxed only while it must be.
CLEARANCE_RAMP_S = 2.0
#: Steps a vehicle dropped from a flying plan coasts on its state's acceleration before it
#: brakes (`braking_motion`): the first step of everyone else is all but fixed by their state.
DROP_COAST_STEPS = 1
#: Largest speed a fixed trajectory may state (m/s), as the scenario's velocity bounds.
SPEED_MAX = RANGES["velocity_max"][1]
_KEYS = {"id", "positions", "velocities", "margin", "start_clearance"}


@dataclass(frozen=True)
class FixedTrajectory:
    """One vehicle's known motion (see the module)."""

    id: str
    positions: FloatArray
    """(M, 3) world ENU positions at t = k dt, k = 0..M-1 (m)."""
    velocities: FloatArray | None = None
    """(M, 3) velocities there (m/s), or None: straight lines between the samples."""
    margin: float = 0.0
    """What the planned vehicles keep from it beyond R (m), once the prediction has had
    time to drift (`margin_at`)."""
    start_clearance: Mapping[str, float] = field(default_factory=dict)
    """Planned vehicles (by id) that start closer than R to it, and the distance each keeps
    from it at first (m, separation metric; at least R means none): the pair's clearance
    then grows back to R + margin (`relief_at`)."""

    def __len__(self) -> int:
        return len(self.positions)

    def motion(self, dt: float, stages: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(p (stages, 3), v (stages, 3), a (stages - 1, 3)) on the grid of `stages` steps'
        ends, the motion inside step k being p_k + s v_k + s^2/2 a_k: the samples, then at
        rest at the last one."""
        m = len(self.positions)
        if stages < m:
            raise ValueError(f"fixed trajectory {self.id!r} has {m} samples, more than "
                             f"the {stages} of the horizon")
        p = np.empty((stages, 3))
        p[:m] = self.positions
        p[m:] = self.positions[-1]
        v = np.zeros((stages, 3))
        if self.velocities is None:
            v[:m - 1] = np.diff(self.positions, axis=0) / dt
        else:
            v[:m - 1] = self.velocities[:m - 1]
        # v_k is the velocity step k leaves with (a given prediction may jump in velocity
        # between steps; its position is continuous)
        a = 2.0 * (p[1:] - p[:-1] - dt * v[:-1]) / (dt * dt)
        return p, v, a

    def state(self, t: ArrayLike, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(position, velocity, acceleration), (T, 3) each, at times `t` (s from its first
        sample, clipped to [0, end]; at rest at the last sample after it)."""
        times = np.atleast_1d(np.asarray(t, dtype=float))
        m = len(self.positions)
        p, v, a = self.motion(dt, m + 1)
        k = np.clip(np.floor(times / dt).astype(np.intp), 0, m - 1)
        s = np.clip(times - k * dt, 0.0, dt)[:, None]
        resting = (times >= (m - 1) * dt)[:, None]
        acc = np.where(resting, 0.0, a[k])
        vel = np.where(resting, 0.0, v[k] + s * a[k])
        pos = np.where(resting, p[m - 1], p[k] + s * v[k] + 0.5 * s * s * a[k])
        return pos, vel, acc

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"id": self.id, "positions": self.positions.tolist()}
        if self.velocities is not None:
            out["velocities"] = self.velocities.tolist()
        if self.margin:
            out["margin"] = self.margin
        if self.start_clearance:
            out["start_clearance"] = dict(self.start_clearance)
        return out

    @staticmethod
    def from_dict(data: Mapping[str, Any], where: str = "fixed[0]",
                  max_samples: int | None = None) -> FixedTrajectory:
        """Parse one fixed trajectory; `ScenarioError` naming the field otherwise."""
        check_keys(data, _KEYS, where, ("id", "positions"))
        fid = check_id(data["id"], f"{where}.id")
        positions = _samples(data["positions"], f"{where}.positions", RANGES["coordinate"],
                             max_samples)
        velocities = None
        if data.get("velocities") is not None:
            velocities = _samples(data["velocities"], f"{where}.velocities",
                                  (-SPEED_MAX, SPEED_MAX), max_samples)
            if len(velocities) != len(positions):
                raise ScenarioError(f"{where}.velocities",
                                    f"must have as many samples as positions "
                                    f"({len(positions)}), got {len(velocities)}")
        margin = check_number(data.get("margin", 0.0), f"{where}.margin", nonneg=True,
                              within="separation_margin")
        raw = data.get("start_clearance", {})
        if not isinstance(raw, Mapping):
            raise ScenarioError(f"{where}.start_clearance",
                                "must be an object {planned vehicle id: clearance in m}")
        start = {check_id(vid, f"{where}.start_clearance"): check_number(
                     c, f"{where}.start_clearance.{vid}", positive=True, within="min_separation")
                 for vid, c in raw.items()}
        return FixedTrajectory(fid, positions, velocities, margin, start)


def _samples(value: Any, name: str, bounds: tuple[float, float], at_most: int | None
             ) -> FloatArray:
    """(M, 3) finite numbers within `bounds`, M >= 1 (at most `at_most`)."""
    rows = check_list(value, name, "samples [x, y, z]",
                      at_most if at_most is not None else 1 << 20)
    if not rows:
        raise ScenarioError(name, "must contain at least one sample")
    for index, row in enumerate(rows):
        if (not isinstance(row, Sequence) or isinstance(row, str) or len(row) != 3
                or any(isinstance(c, bool) or not isinstance(c, int | float) for c in row)):
            raise ScenarioError(f"{name}[{index}]", "must be a list of 3 numbers [x, y, z]")
    try:
        array = np.array(rows, dtype=float)
    except OverflowError:
        array = np.full((len(rows), 3), np.inf)
    bad = ~(np.isfinite(array) & (array >= bounds[0]) & (array <= bounds[1]))
    if bad.any():
        index, axis = (int(x) for x in np.argwhere(bad)[0])
        raise ScenarioError(f"{name}[{index}][{axis}]",
                            f"must be a finite number between {bounds[0]:g} and "
                            f"{bounds[1]:g}")
    return array


def parse_fixed(data: Mapping[str, Any], vehicle_ids: Sequence[str], steps: int
                ) -> tuple[FixedTrajectory, ...]:
    """The scenario's `fixed` list: ids unique and distinct from the planned vehicles', at
    most steps + 1 samples each (the motion after the horizon would go unchecked)."""
    raw = check_list(data.get("fixed", []), "fixed", "fixed trajectories", MAX_FIXED)
    planned = set(vehicle_ids)
    seen: dict[str, int] = {}
    out = []
    for index, item in enumerate(raw):
        where = f"fixed[{index}]"
        if isinstance(item, Mapping) and isinstance(item.get("positions"), Sequence) \
                and not isinstance(item["positions"], str) and len(item["positions"]) > steps + 1:
            raise ScenarioError(f"{where}.positions",
                                f"at most steps + 1 = {steps + 1} samples (the horizon), "
                                f"got {len(item['positions'])}")
        fixed = FixedTrajectory.from_dict(item, where, steps + 1)
        if fixed.id in seen:
            raise ScenarioError(f"{where}.id",
                                f"duplicate id {fixed.id!r} (also fixed[{seen[fixed.id]}])")
        if fixed.id in planned:
            raise ScenarioError(f"{where}.id", f"{fixed.id!r} is also a planned vehicle")
        for vid in fixed.start_clearance:
            if vid not in planned:
                raise ScenarioError(f"{where}.start_clearance.{vid}",
                                    f"{vid!r} is not a planned vehicle")
        seen[fixed.id] = index
        out.append(fixed)
    return tuple(out)


@dataclass(frozen=True)
class FixedSet:
    """Every fixed trajectory of a scenario as arrays on its grid (built once)."""

    ids: list[str]
    positions: FloatArray
    """(F, K+1, 3)."""
    velocities: FloatArray
    """(F, K+1, 3)."""
    accelerations: FloatArray
    """(F, K, 3)."""
    margins: FloatArray
    """(F,) full margins."""
    interval_margins: FloatArray
    """(F, K) the margin over each step: `margin_at` its end (the largest over it)."""
    deficits: FloatArray | None = None
    """(N, F) how much closer than R each planned vehicle starts from each fixed one
    (`FixedTrajectory.start_clearance`; 0 for a pair that keeps R), None: no pair."""
    interval_relief: FloatArray | None = None
    """(K,) the share of a deficit forgiven over each step: `relief_at` its end (the least
    over it)."""

    def step_margins(self) -> FloatArray:
        """(F, K+1) the margin at each step's instant (0 at the start)."""
        return np.concatenate([np.zeros((len(self.ids), 1)), self.interval_margins], axis=1)

    def interval_extra(self, vehicle: IntArray, fixed: IntArray, k: IntArray) -> FloatArray:
        """What planned `vehicle` keeps from `fixed` beyond R over interval `k` (m; arrays of
        one length): the margin less the pair's forgiven deficit, both at the interval's end
        (the largest need over it)."""
        extra = self.interval_margins[fixed, k]
        if self.deficits is None or self.interval_relief is None:
            return extra
        return extra - self.deficits[vehicle, fixed] * self.interval_relief[k]

    def step_extra(self, vehicle: IntArray, fixed: IntArray) -> FloatArray:
        """(pairs, K+1) what each (vehicle, fixed) pair keeps beyond R at each step's
        instant: the margin (0 at the start) less the forgiven deficit (all of it there)."""
        extra = self.step_margins()[fixed]
        if self.deficits is None or self.interval_relief is None:
            return extra
        relief = np.concatenate([[1.0], self.interval_relief])
        relieved: FloatArray = extra - self.deficits[vehicle, fixed][:, None] * relief[None, :]
        return relieved

    @staticmethod
    def build(fixed: Sequence[FixedTrajectory], dt: float, steps: int,
              vehicle_ids: Sequence[str] = (), separation: float = 0.0) -> FixedSet:
        """The arrays of `fixed` on `steps` steps of `dt`; `vehicle_ids` and R
        (`separation`) place each `start_clearance` as a deficit."""
        motions = [f.motion(dt, steps + 1) for f in fixed]
        margins = np.array([f.margin for f in fixed], dtype=float)
        ends = dt * np.arange(1, steps + 1)
        ramp = margin_at(1.0, ends, dt)
        if not motions:
            return FixedSet([], np.zeros((0, steps + 1, 3)), np.zeros((0, steps + 1, 3)),
                            np.zeros((0, steps, 3)), margins, np.zeros((0, steps)))
        deficits = None
        if any(f.start_clearance for f in fixed):
            row = {vid: n for n, vid in enumerate(vehicle_ids)}
            deficits = np.zeros((len(vehicle_ids), len(fixed)))
            for m, f in enumerate(fixed):
                for vid, clearance in f.start_clearance.items():
                    deficits[row[vid], m] = max(0.0, separation - clearance)
        return FixedSet([f.id for f in fixed],
                        np.stack([m[0] for m in motions]), np.stack([m[1] for m in motions]),
                        np.stack([m[2] for m in motions]), margins,
                        margins[:, None] * ramp[None, :], deficits,
                        None if deficits is None else relief_at(ends, dt))

    def __len__(self) -> int:
        return len(self.ids)


def margin_at(margin: float, t: ArrayLike, dt: float) -> FloatArray:
    """The margin required at times `t` (s): none over the first step (the prediction
    starts where the vehicle is), then growing to `margin` over `MARGIN_RAMP_S`."""
    return margin * np.clip((np.asarray(t, dtype=float) - dt) / MARGIN_RAMP_S, 0.0, 1.0)


def relief_at(t: ArrayLike, dt: float) -> FloatArray:
    """The share of a pair's start deficit still forgiven at times `t` (s): all of it over
    the first step (the state fixes it), then falling linearly to none over
    `CLEARANCE_RAMP_S`."""
    return 1.0 - np.clip((np.asarray(t, dtype=float) - dt) / CLEARANCE_RAMP_S, 0.0, 1.0)


def _stop(position: FloatArray, velocity: FloatArray, dt: float, deceleration: float
          ) -> tuple[FloatArray, FloatArray]:
    """Samples of braking along the velocity at `deceleration` to rest (positions and
    velocities at t = k dt, the last at rest)."""
    speed = float(np.linalg.norm(velocity))
    if speed < 1e-9:
        return position[None, :].copy(), np.zeros((1, 3))
    direction = velocity / speed
    stop_time = speed / deceleration
    t = np.arange(0.0, stop_time + dt, dt)
    t = np.minimum(t, stop_time)
    along = speed * t - 0.5 * deceleration * t * t
    positions = position + along[:, None] * direction
    velocities = (speed - deceleration * t)[:, None] * direction
    positions[-1] = position + (0.5 * speed * stop_time) * direction
    velocities[-1] = 0.0
    return positions, velocities


def _coast(position: FloatArray, velocity: FloatArray, acceleration: ArrayLike | None,
           dt: float, steps: int) -> tuple[FloatArray, FloatArray]:
    """Samples of `steps` steps flown at the state's constant `acceleration` (none: at its
    velocity), the last one included: where a braking that starts after them begins."""
    a = np.zeros(3) if acceleration is None else np.asarray(acceleration,
                                                              dtype=float).reshape(3)
    t = dt * np.arange(steps + 1)[:, None]
    return position + t * velocity + 0.5 * t * t * a, velocity + t * a


def _braking(position: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike | None,
             dt: float, deceleration: float, coast_steps: int
             ) -> tuple[FloatArray, FloatArray]:
    """Samples of coasting `coast_steps` steps, then braking to rest (`_stop`)."""
    if coast_steps < 0:
        raise ValueError("coast_steps must not be negative")
    p = np.asarray(position, dtype=float).reshape(3)
    v = np.asarray(velocity, dtype=float).reshape(3)
    ahead_p, ahead_v = _coast(p, v, acceleration, dt, coast_steps)
    positions, velocities = _stop(ahead_p[-1], ahead_v[-1], dt, deceleration)
    return (np.concatenate([ahead_p[:-1], positions]),
            np.concatenate([ahead_v[:-1], velocities]))


def braking_motion(vehicle_id: str, position: ArrayLike, velocity: ArrayLike, dt: float,
                   deceleration: float, *, margin: float = 0.0,
                   acceleration: ArrayLike | None = None, coast_steps: int = 0
                   ) -> FixedTrajectory:
    """A vehicle told to hold: it brakes along its velocity at `deceleration` (m/s^2) and
    rests where it stopped.

    coast_steps: steps it first flies on at its state's `acceleration` (a vehicle taken off
    a plan at a switch instant: over the first step the others' motion is all but fixed by
    their state too, and only a dropped vehicle that goes on as the plan had it keeps the
    separation that plan proved; braking at once can leave a neighbour passing at R no way
    to clear it)."""
    if not deceleration > 0.0:
        raise ValueError("deceleration must be positive")
    positions, velocities = _braking(position, velocity, acceleration, dt, deceleration,
                                     coast_steps)
    return FixedTrajectory(vehicle_id, positions, velocities, margin)


def landing_motion(vehicle_id: str, position: ArrayLike, velocity: ArrayLike, dt: float,
                   deceleration: float, descent_speed: float, floor: float, *,
                   margin: float = 0.0, acceleration: ArrayLike | None = None,
                   coast_steps: int = 0, hold_s: float = 0.0) -> FixedTrajectory:
    """A vehicle told to land: it coasts and brakes as in `braking_motion`, holds there for
    `hold_s` (s: an autopilot's failsafe delay), then goes straight down at
    `descent_speed` (m/s) to height `floor` (m), and rests there."""
    if not (deceleration > 0.0 and descent_speed > 0.0 and hold_s >= 0.0):
        raise ValueError("deceleration and descent_speed must be positive, hold_s not "
                         "negative")
    positions, velocities = _braking(position, velocity, acceleration, dt, deceleration,
                                     coast_steps)
    waits = math.ceil(hold_s / dt - 1e-9)
    if waits:
        positions = np.concatenate([positions, np.repeat(positions[-1:], waits, axis=0)])
        velocities = np.concatenate([velocities, np.zeros((waits, 3))])
    top = positions[-1]
    drop = max(0.0, float(top[2]) - floor)
    if drop > 0.0:
        n = max(1, math.ceil(drop / (descent_speed * dt)))
        z = top[2] - drop * np.arange(1, n + 1) / n
        down = np.repeat(top[None, :], n, axis=0)
        down[:, 2] = z
        speed = drop / (n * dt)
        vz = np.zeros((n, 3))
        vz[:-1, 2] = -speed
        velocities = velocities.copy()
        velocities[-1, 2] = -speed  # the stop's last sample starts the descent
        positions = np.concatenate([positions, down])
        velocities = np.concatenate([velocities, vz])
    return FixedTrajectory(vehicle_id, positions, velocities, margin)


def dropped_motion(vehicle_id: str, position: ArrayLike, velocity: ArrayLike,
                   acceleration: ArrayLike, dt: float, action: str, *, deceleration: float,
                   hardest: float, low: FloatArray, high: FloatArray, descent_speed: float,
                   floor: float) -> FixedTrajectory:
    """What a vehicle dropped from a flying plan at a switch instant does: it coasts
    `DROP_COAST_STEPS` on its state's acceleration, then brakes at `deceleration` and rests
    ("hold") or descends at `descent_speed` to `floor` ("land"). Where that would carry it
    out of the workspace [low, high] (a plan braking hard towards a wall, followed by a
    gentler braking), it brakes at once at `hardest` (the boxes' bound) instead."""
    def motion(coast_steps: int, rate: float) -> FixedTrajectory:
        if action == "hold":
            return braking_motion(vehicle_id, position, velocity, dt, rate,
                                  acceleration=acceleration, coast_steps=coast_steps)
        return landing_motion(vehicle_id, position, velocity, dt, rate, descent_speed, floor,
                              acceleration=acceleration, coast_steps=coast_steps)

    first = motion(DROP_COAST_STEPS, deceleration)
    if ((first.positions >= low - 1e-9) & (first.positions <= high + 1e-9)).all():
        return first
    return motion(0, max(deceleration, hardest))


def check_fixed_clear(fixed: Sequence[FixedTrajectory], separation: float, scale: FloatArray,
                      starts: FloatArray, goals: FloatArray, ids: Sequence[str] = ()) -> None:
    """Refuses a start within R (or the pair's `start_clearance`) of a fixed vehicle's first
    position, or a goal within R + margin of its last (where it rests): no plan could keep
    it. Names the vehicle and the fixed trajectory."""
    for f in fixed:
        start_need = np.array([min(separation, f.start_clearance.get(vid, separation))
                               for vid in ids]) if f.start_clearance else separation
        for label, points, at, when, need in (
                ("start", starts, f.positions[0], "at its start", start_need),
                ("goal", goals, f.positions[-1], "where it rests", separation + f.margin)):
            d = np.linalg.norm((points - at) / scale, axis=1)
            least = np.broadcast_to(need, d.shape)
            n = int(np.argmin(d - least))
            if d[n] < least[n]:
                raise ScenarioError(f"vehicles[{n}].{label}",
                                    f"is {d[n]:.3f} m from fixed vehicle {f.id!r} {when}, "
                                    f"closer than {least[n]:g} m")
