"""Takeoff from and landing on a ground grid: the first and last legs of a show sequence.

A sequence's `takeoff` gives the drones' homes on the ground (z = 0): a list, one [x, y] per
vehicle in vehicle order, or a grid (`origin` [x, y], `columns`, `rows`, `spacing` [dx, dy],
filled row by row). Ground grids are often closer than R in some direction, so the takeoff is
staggered in waves: two homes closer than R (in the separation metric, with
`WAVE_SLACK`) never share a wave (a greedy colouring of the grid). Wave 0 climbs
straight up first, to the highest layer, wave 1 once wave 0 is up, to the layer `R` (times
the vertical separation scale, with `WAVE_SLACK`) below, and so on down to the lowest layer at
`height` (default `DEFAULT_HEIGHT`). Each climb is planned by the planner itself as a
one-vehicle leg (v, a, jerk, thrust and body rates within the limits) and flown by every drone
of the wave. Then one planned leg takes the layered fleet to the first formation. The landing
is the mirror: a planned leg from the last formation to the layers above the landing slots
(`landing`: a list or grid of slots, the takeoff homes by default; with `assignment` free,
the default, any drone takes any free slot), then the waves descend, the lowest layer first,
each along its climb reversed in time.

Ground contact: a drone stands at its home, at rest, until its wave climbs, and stands on its
slot after touchdown. Separation applies between two drones whenever both are off the ground
(`planner.verification.ground`); a drone parked on the ground is not a drone in the air.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from planner.errors import ScenarioError
from planner.methods.assignment import assign_goals
from planner.model.scenario import AUTO_STEPS, MAX_VEHICLES, check_keys, check_number
from planner.result import Plan
from planner.types import FloatArray

__all__ = ["DEFAULT_HEIGHT", "GroundLegs", "GroundMotion", "Takeoff", "ground_legs",
           "landing_motion", "parse_takeoff", "takeoff_motion", "waves"]

#: Height of the lowest layer a wave climbs to, unless `takeoff.height` says otherwise (m).
DEFAULT_HEIGHT = 2.0
#: Homes closer than R times (1 + this) take off in different waves, and layers are R times
#: (1 + this) apart: room for the verifier's tolerance and the planner's rounding.
WAVE_SLACK = 0.05
#: Most cells a dense landing assignment may weigh (slots x drones) when slots outnumber
#: drones; equal counts use the sparse, certified assignment.
MAX_DENSE_CELLS = 25_000_000
_TAKEOFF_KEYS = {"homes", "grid", "height", "duration"}
_LANDING_KEYS = {"homes", "grid", "duration", "assignment"}
_GRID_KEYS = {"origin", "columns", "rows", "spacing"}


@dataclass(frozen=True)
class GroundLegs:
    """A sequence's takeoff and landing: where each drone stands, in which wave it leaves
    or reaches the ground, and the legs to plan (picklable scenario dicts)."""

    homes: FloatArray
    """(N, 3) each vehicle's home, z = 0."""
    takeoff_waves: NDArray[np.intp]
    liftoff: FloatArray
    """(N, 3) each vehicle above its home, at its wave's layer."""
    slots: FloatArray
    """(N, 3) each vehicle's landing slot, z = 0."""
    landing_waves: NDArray[np.intp]
    approach: FloatArray
    """(N, 3) each vehicle above its slot, at its landing wave's layer."""
    climbs: tuple[dict[str, Any], ...]
    """One one-vehicle climb per distinct layer height (`climb_heights`), ground to layer."""
    climb_heights: tuple[float, ...]
    takeoff_leg: dict[str, Any]
    """Layers -> the first formation."""
    landing_leg: dict[str, Any]
    """The last formation -> the layers above the slots."""
    slot_index: tuple[int, ...]
    """Which slot of the landing grid each vehicle takes."""


def _homes(raw: Mapping[str, Any], where: str, at_least: int, exactly: bool) -> FloatArray:
    """The homes of a `takeoff` or `landing` block: a list of [x, y] or a grid."""
    if ("homes" in raw) == ("grid" in raw):
        raise ScenarioError(where, "give either homes (one [x, y] per vehicle) or grid "
                                   "{origin, columns, rows, spacing}")
    if "homes" in raw:
        value = raw["homes"]
        if not isinstance(value, Sequence) or isinstance(value, str):
            raise ScenarioError(f"{where}.homes", "must be a list of [x, y] positions")
        out = np.zeros((len(value), 3))
        for n, point in enumerate(value):
            if (not isinstance(point, Sequence) or isinstance(point, str)
                    or len(point) not in (2, 3) or (len(point) == 3 and point[2] != 0)):
                raise ScenarioError(f"{where}.homes[{n}]", "must be [x, y] (on the ground, "
                                                           "z = 0)")
            for axis in range(2):
                out[n, axis] = check_number(point[axis], f"{where}.homes[{n}][{axis}]")
    else:
        grid = raw["grid"]
        field = f"{where}.grid"
        check_keys(grid, _GRID_KEYS, field, ("origin", "columns", "rows", "spacing"))
        columns, rows = grid["columns"], grid["rows"]
        for key, count in (("columns", columns), ("rows", rows)):
            if not isinstance(count, int) or isinstance(count, bool) or not 1 <= count \
                    <= MAX_VEHICLES:
                raise ScenarioError(f"{field}.{key}", f"must be a whole number 1..{MAX_VEHICLES}")
        if columns * rows > 4 * MAX_VEHICLES:
            raise ScenarioError(field, f"at most {4 * MAX_VEHICLES} cells")
        origin = _pair(grid["origin"], f"{field}.origin", positive=False)
        spacing = _pair(grid["spacing"], f"{field}.spacing", positive=True)
        r, c = np.divmod(np.arange(columns * rows), columns)
        out = np.zeros((columns * rows, 3))
        out[:, 0] = origin[0] + c * spacing[0]
        out[:, 1] = origin[1] + r * spacing[1]
    if (exactly and len(out) != at_least) or len(out) < at_least:
        need = f"{at_least}" if exactly else f"at least {at_least}"
        raise ScenarioError(f"{where}.{'homes' if 'homes' in raw else 'grid'}",
                            f"has {len(out)} places; the fleet needs {need}, one per vehicle")
    return out


def _pair(value: Any, field: str, *, positive: bool) -> FloatArray:
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise ScenarioError(field, "must be [x, y]")
    return np.array([check_number(x, f"{field}[{i}]", positive=positive)
                     for i, x in enumerate(value)])


def waves(homes: FloatArray, scale: FloatArray, separation: float) -> NDArray[np.intp]:
    """Each home's wave: homes closer than R (1 + `WAVE_SLACK`) in the separation metric
    get different waves (greedy colouring in home order)."""
    tree = cKDTree(homes / scale)
    pairs = tree.query_pairs(separation * (1.0 + WAVE_SLACK), output_type="ndarray")
    neighbours: list[list[int]] = [[] for _ in range(len(homes))]
    for i, j in pairs.tolist():
        neighbours[max(i, j)].append(min(i, j))
    out = np.zeros(len(homes), dtype=np.intp)
    for n in range(len(homes)):
        taken = {int(out[m]) for m in neighbours[n]}
        out[n] = next(w for w in range(len(taken) + 1) if w not in taken)
    return out


def _layers(wave: NDArray[np.intp], base: float, step: float, places: FloatArray) -> FloatArray:
    """Each drone above its place at its wave's layer: wave 0 highest."""
    count = int(wave.max()) + 1
    out = places.copy()
    out[:, 2] = base + (count - 1 - wave) * step
    return out


def _slots(last: FloatArray, slots: FloatArray, scale: FloatArray, where: str
           ) -> NDArray[np.intp]:
    """Which slot each drone lands on, the total squared distance least."""
    if len(slots) == len(last):
        return assign_goals(last, slots, scale)
    if len(slots) * len(last) > MAX_DENSE_CELLS:
        raise ScenarioError(where, f"{len(slots)} slots for {len(last)} drones is too many to "
                                   f"weigh: give as many slots as drones")
    cost = (((last[:, None, :] - slots[None, :, :]) / scale) ** 2).sum(axis=2)
    rows, columns = linear_sum_assignment(cost)
    order = np.empty(len(last), dtype=np.intp)
    order[rows] = columns
    return order


def _climb(name: str, shared: Mapping[str, Any], height: float, home: FloatArray
           ) -> dict[str, Any]:
    """One vehicle straight up from `home` on the ground to `height` (the planner chooses
    the time); every drone of a wave flies its z profile."""
    x, y = float(home[0]), float(home[1])
    return {"name": f"{name}: climb to {height:g} m", **shared, "steps": AUTO_STEPS,
            "vehicles": [{"id": "climb", "start": [x, y, 0.0], "goal": [x, y, height]}]}


@dataclass(frozen=True)
class Takeoff:
    """Where the drones stand and the layers they climb to (before any formation)."""

    homes: FloatArray
    waves: NDArray[np.intp]
    liftoff: FloatArray
    base: float
    """The lowest layer's height (m)."""
    step: float
    """Height between layers (m)."""


def parse_takeoff(data: Mapping[str, Any], shared: Mapping[str, Any], scale: FloatArray,
                  count: int) -> Takeoff | None:
    """The sequence's `takeoff` (None without one); `ScenarioError` naming the field. A
    `landing` needs a takeoff: a show that lands on the ground took off from it."""
    if "takeoff" not in data:
        if "landing" in data:
            raise ScenarioError("landing", "needs a takeoff: a show that lands on the ground "
                                           "took off from it")
        return None
    takeoff = data["takeoff"]
    if isinstance(takeoff, Mapping) and "fleet" in takeoff:
        raise ScenarioError("takeoff.fleet", "a fleet file is read by `fleetplan plan` "
                                             "(--takeoff-fleet), which fills takeoff.homes from "
                                             "its homes; here give takeoff.homes or "
                                             "takeoff.grid")
    check_keys(takeoff, _TAKEOFF_KEYS, "takeoff", ())
    separation = check_number(shared["min_separation"], "min_separation", positive=True)
    limits = shared["limits"]
    try:
        floor = float(limits["position_min"][2])
    except (TypeError, KeyError, IndexError, ValueError):
        floor = 0.0  # malformed limits: the legs' own checks name them
    if floor > 0:
        raise ScenarioError("limits.position_min[2]", "must be 0 or below with a takeoff: the "
                                                      "ground (z = 0) is inside the workspace")
    homes = _homes(takeoff, "takeoff", count, exactly=True)
    base = check_number(takeoff.get("height", DEFAULT_HEIGHT), "takeoff.height", positive=True)
    step = separation * float(scale[2]) * (1.0 + WAVE_SLACK)
    up = waves(homes, scale, separation)
    return Takeoff(homes=homes, waves=up, liftoff=_layers(up, base, step, homes), base=base,
                   step=step)


def ground_legs(data: Mapping[str, Any], takeoff: Takeoff, *, name: str, ids: Sequence[str],
                shared: Mapping[str, Any], scale: FloatArray, first: FloatArray,
                last: FloatArray) -> GroundLegs:
    """The takeoff and landing legs around the formations (`first`, `last`: the first and
    last formations' points in vehicle order); `ScenarioError` naming the field."""
    count = len(ids)
    separation = float(shared["min_separation"])
    landing = data.get("landing", {})
    check_keys(landing, _LANDING_KEYS, "landing", ())
    places = _homes(landing, "landing", count, exactly=False) if (
        "homes" in landing or "grid" in landing) else takeoff.homes
    assignment = landing.get("assignment", "free")
    if assignment not in ("fixed", "free"):
        raise ScenarioError("landing.assignment", f"must be 'fixed' or 'free', got "
                                                  f"{assignment!r}")
    if assignment == "fixed":
        if len(places) != count:
            raise ScenarioError("landing.assignment", "fixed needs one slot per vehicle")
        order = np.arange(count)
    else:
        above = places.copy()
        above[:, 2] = takeoff.base
        order = _slots(last, above, scale, "landing")
    slots = places[order]
    down = waves(slots, scale, separation)
    approach = _layers(down, takeoff.base, takeoff.step, slots)
    heights = sorted({float(z) for z in np.concatenate([takeoff.liftoff[:, 2],
                                                         approach[:, 2]])})
    top = shared["limits"]["position_max"][2]
    if heights[-1] > top:
        raise ScenarioError("limits.position_max[2]", f"the ground legs' layers reach "
                                                      f"{heights[-1]:g} m: raise it, or lower "
                                                      f"takeoff.height")

    def leg(label: str, starts: FloatArray, goals: FloatArray, duration: Any) -> dict[str, Any]:
        steps = AUTO_STEPS if duration in (None, AUTO_STEPS) else _steps(duration, shared,
                                                                          label)
        return {"name": f"{name}: {label}", **shared, "steps": steps,
                "vehicles": [{"id": vid, "start": s.tolist(), "goal": g.tolist()}
                             for vid, s, g in zip(ids, starts, goals, strict=True)]}

    return GroundLegs(
        homes=takeoff.homes, takeoff_waves=takeoff.waves, liftoff=takeoff.liftoff,
        slots=slots, landing_waves=down, approach=approach,
        climbs=tuple(_climb(name, shared, z, takeoff.homes[0]) for z in heights),
        climb_heights=tuple(heights),
        takeoff_leg=leg("takeoff", takeoff.liftoff, first, data["takeoff"].get("duration")),
        landing_leg=leg("landing", last, approach, landing.get("duration")),
        slot_index=tuple(int(i) for i in order),
    )


def _steps(duration: Any, shared: Mapping[str, Any], label: str) -> int:
    field = f"{label}.duration"
    seconds = check_number(duration, field, positive=True)
    dt = float(shared["dt"])
    steps = round(seconds / dt)
    if steps < 1 or not math.isclose(steps * dt, seconds, rel_tol=1e-6, abs_tol=1e-9):
        raise ScenarioError(field, f"must be a whole number of steps of dt = {dt:g} s, or "
                                   f'"{AUTO_STEPS}"')
    return steps


@dataclass(frozen=True)
class GroundMotion:
    """A takeoff or landing as stitched arrays: p, v (N, K + 1, 3), a (N, K, 3), and each
    drone's step of lift-off (takeoff) or touchdown (landing)."""

    p: FloatArray
    v: FloatArray
    a: FloatArray
    moment: NDArray[np.intp]


def _profile(climbs: Mapping[float, Plan], height: float) -> tuple[FloatArray, ...]:
    """The climb to `height` as (z, vz, az) on its steps, straight up (x, y untouched), its
    ends exactly on the ground and the layer at rest (the solver's are within 1e-9)."""
    plan = climbs[height]
    z, vz = plan.positions()[0, :, 2].copy(), plan.velocities()[0, :, 2].copy()
    z[0], z[-1], vz[0], vz[-1] = 0.0, height, 0.0, 0.0
    return z, vz, plan.accelerations()[0, :, 2]


def _waves_motion(places: FloatArray, layers: FloatArray, wave: NDArray[np.intp],
                  climbs: Mapping[float, Plan], order: Sequence[int], up: bool) -> GroundMotion:
    """Every wave in `order`, one after the other, between the ground and its layer: climbs
    (`up`) or the same climbs reversed in time (descents)."""
    profiles = {w: _profile(climbs, float(layers[wave == w][0, 2])) for w in order}
    lengths = {w: len(profiles[w][2]) for w in order}
    total = sum(lengths.values())
    n = len(places)
    p = np.repeat((places if up else layers)[:, None, :], total + 1, axis=1)
    v = np.zeros((n, total + 1, 3))
    a = np.zeros((n, total, 3))
    moment = np.zeros(n, dtype=np.intp)
    clock = 0
    for w in order:
        z, vz, az = profiles[w]
        if not up:  # the climb backwards in time: positions reversed, velocities negated
            z, vz, az = z[::-1], -vz[::-1], az[::-1]
        k = lengths[w]
        rows = np.flatnonzero(wave == w)
        p[rows, clock:clock + k + 1, 2] = z[None, :]
        v[rows, clock:clock + k + 1, 2] = vz[None, :]
        a[rows, clock:clock + k, 2] = az[None, :]
        after = places if not up else layers
        p[rows, clock + k + 1:, 2] = after[rows, 2][:, None]
        moment[rows] = clock if up else clock + k
        clock += k
    return GroundMotion(p, v, a, moment)


def takeoff_motion(ground: GroundLegs, climbs: Mapping[float, Plan], leg: Plan) -> GroundMotion:
    """From the homes to the first formation: the waves' climbs, then the planned leg."""
    count = int(ground.takeoff_waves.max()) + 1
    rise = _waves_motion(ground.homes, ground.liftoff, ground.takeoff_waves, climbs,
                         list(range(count)), up=True)
    return GroundMotion(
        np.concatenate([rise.p[:, :-1], leg.positions()], axis=1),
        np.concatenate([rise.v[:, :-1], leg.velocities()], axis=1),
        np.concatenate([rise.a, leg.accelerations()], axis=1), rise.moment)


def landing_motion(ground: GroundLegs, climbs: Mapping[float, Plan], leg: Plan) -> GroundMotion:
    """From the last formation to the slots: the planned leg, then the waves' descents, the
    lowest layer first, and one step at rest on the ground (a descent ends braking, as a
    climb starts: the show ends with no acceleration left)."""
    count = int(ground.landing_waves.max()) + 1
    fall = _waves_motion(ground.slots, ground.approach, ground.landing_waves, climbs,
                         list(range(count - 1, -1, -1)), up=False)
    steps = leg.scenario.steps
    n = len(ground.slots)
    return GroundMotion(
        np.concatenate([leg.positions()[:, :-1], fall.p, fall.p[:, -1:]], axis=1),
        np.concatenate([leg.velocities()[:, :-1], fall.v, np.zeros((n, 1, 3))], axis=1),
        np.concatenate([leg.accelerations(), fall.a, np.zeros((n, 1, 3))], axis=1),
        fall.moment + steps)
