"""Each vehicle's own link-loss failsafe, read and set before arming, told, and put back.

When the ground station is gone (its process killed, its computer or radio dead), no
setpoint arrives and each vehicle flies its own link-loss failsafe (its autopilot's:
`gcs.autopilot.base.Autopilot.failsafe`; on PX4, COM_OF_LOSS_T after the last setpoint it
leaves OFFBOARD and holds in Position for COM_FAIL_ACT_T, then takes COM_OBL_RC_ACT). Before
arming, `set_failsafe` reads its parameters (PARAM_REQUEST_READ) and sets, from the plan
(`Autopilot.failsafe_settings`):

- hover for a vehicle whose column ever comes within R of another's horizontally
  (`column_conflicts`, autopilot-free: no autopilot failsafe moves a vehicle sideways, so
  landing two such vehicles straight down brings them that close; hovering where the
  station left them keeps the plan's separation in 3D, and the operator lands them by plan:
  `fleetplan fleet land --plan`), land for the others (Return climbs and crosses the others'
  paths);
- the delay staggered by altitude layer (`layer_delays`): the lowest layer lands after the
  autopilots' default 5 s, each layer above only once the one below has had time to reach
  the ground, so no vehicle descends onto one still hovering below it.

An ArduCopter's counterparts (`gcs.autopilot.ardupilot`): `FS_GCS_ENABLE` set to Land and
`FS_GCS_TIMEOUT` staggered the same way; `GUID_TIMEOUT` kept. Which parameters, and what they
mean, is the vehicle's `Autopilot`'s to say.

Every value is read back from the vehicle's PARAM_VALUE; `v.failsafe` then holds what the
vehicle does (the flight's predictions of a lost vehicle use it), and a `failsafe` event says
it. A parameter that cannot be read or set refuses the flight (`FailsafeNotSet`) unless the
fleet option `failsafe` is `try`. After the flight `restore_failsafe` puts back the values
read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from gcs.autopilot import LinkLossFailsafe
from gcs.errors import FailsafeNotSet
from gcs.flight.procedure.context import FlightContext
from gcs.flight.procedure.params import ParamError, read_param, set_param
from gcs.flight.procedure.vehicle import VehicleStatus
from gcs.phases import EventKind
from planner import Plan
from planner.types import FloatArray

__all__ = ["LAYER_BASE_DELAY_S", "LAYER_GAP_M", "ColumnConflict", "ParamError",
           "column_conflicts", "failsafe_record", "layer_delays", "read_param",
           "restore_failsafe", "set_failsafe", "set_param", "stacked_columns"]

#: The lowest layer's delay (s): the default of both autopilots' failsafe delays (PX4's
#: COM_FAIL_ACT_T, ArduPilot's FS_GCS_TIMEOUT).
LAYER_BASE_DELAY_S = 5.0
#: Vehicles whose planned heights differ by less than this (m) are one layer.
LAYER_GAP_M = 0.3
#: A layer above starts down this long (s) after the one below should be on the ground.
LAYER_SETTLE_S = 1.0
#: COM_FAIL_ACT_T's largest value (PX4's documented maximum, s).
ACTION_DELAY_MAX = 25.0
#: Columns closer than R by more than this (m) meet (`column_conflicts`): a straight-down
#: landing of the two keeps at least R less this.
STACKED_TOLERANCE = 0.05
#: The plan's samples per second the columns are compared at (and followed between).
COLUMN_RATE_HZ = 10.0
#: Points per sample step at which a pair found near is followed between its samples.
BETWEEN = 10


def layer_delays(plan: Plan, land_speed: float) -> list[float]:
    """COM_FAIL_ACT_T per vehicle of `plan` (in its order): PX4's default 5 s for the lowest
    altitude layer (vehicles whose highest planned point lies within `LAYER_GAP_M` of each
    other), and for each layer above, the one below's delay plus the time its highest
    vehicle takes to descend to the floor at `land_speed` and `LAYER_SETTLE_S`; at most
    `ACTION_DELAY_MAX`."""
    floor = float(plan.scenario.limits.position_min[2])
    tops = plan.positions()[:, :, 2].max(axis=1) - floor
    order = np.argsort(tops, kind="stable")
    delays = np.empty(len(tops))
    delay = LAYER_BASE_DELAY_S
    layer_top = layer_start = float(tops[order[0]]) if len(order) else 0.0
    for i in order:
        top = float(tops[i])
        if top - layer_start > LAYER_GAP_M:  # a new layer: after the one below is down
            delay += layer_top / land_speed + LAYER_SETTLE_S
            layer_start = top
        layer_top = top
        delays[i] = min(delay, ACTION_DELAY_MAX)
    return [round(float(d), 1) for d in delays]


@dataclass(frozen=True)
class ColumnConflict:
    """Where the plan brings one vehicle's column closest to another's (below the clearance
    `column_conflicts` was asked for)."""

    other: str
    """The other vehicle."""
    gap: float
    """Their horizontal distance then (m, the plan's separation metric)."""
    t: float
    """When (plan time, s)."""
    above: bool
    """This vehicle is the higher of the two then."""


def column_conflicts(plan: Plan, clearance: float, rate: float = COLUMN_RATE_HZ
                     ) -> dict[str, ColumnConflict]:
    """Every vehicle whose column (its horizontal position, in the plan's separation metric)
    comes closer than `clearance` less `STACKED_TOLERANCE` to another's at the same instant
    of the plan, with the closest such other: a station lost then and a straight-down
    landing bring them that close. The plan is sampled at `rate` Hz into one k-d tree, the
    sample index as a third coordinate spaced wider than the reach, so that only pairs of
    one instant are found (no loop over samples or pairs); the reach is widened by how far
    two columns can close in half a sample, and each pair found is followed between its
    samples (`_between`), so a crossing between two samples is not missed."""
    scenario = plan.scenario
    times = np.arange(0.0, scenario.horizon + 1e-9, 1.0 / rate)
    sample = plan.sample(times)
    p, v = sample.position, sample.velocity  # (N, T, 3)
    n, m = p.shape[:2]
    reach = clearance - STACKED_TOLERANCE
    if n < 2 or reach <= 0:
        return {}
    scale = np.asarray(scenario.separation_scale, dtype=float)[:2]
    xy, vxy = p[:, :, :2] / scale, v[:, :, :2] / scale
    speed = float(np.linalg.norm(vxy, axis=2).max())
    wider = reach + speed / rate  # two columns, each half a sample either way
    k = np.broadcast_to(np.arange(m, dtype=float), (n, m))
    points = np.concatenate([xy, (2.0 * wider + 1.0) * k[:, :, None]], axis=2).reshape(-1, 3)
    pairs = cKDTree(points).query_pairs(wider, output_type="ndarray")
    if len(pairs) == 0:
        return {}
    gaps, at = _between(xy.reshape(-1, 2), vxy.reshape(-1, 2), pairs, m, 1.0 / rate)
    near = gaps < reach
    pairs, gaps, at = pairs[near], gaps[near], at[near]
    if len(pairs) == 0:
        return {}
    who = np.concatenate([pairs[:, 0], pairs[:, 1]])  # flat index: vehicle * m + sample
    other = np.concatenate([pairs[:, 1], pairs[:, 0]])
    gap = np.concatenate([gaps, gaps])
    when = np.concatenate([at, at])
    order = np.lexsort((when, gap, who // m))  # per vehicle: smallest gap, then earliest
    first = order[np.unique(who[order] // m, return_index=True)[1]]
    ids = scenario.ids
    z = p[:, :, 2].reshape(-1)
    return {ids[int(who[f] // m)]: ColumnConflict(
        ids[int(other[f] // m)], float(gap[f]), float(when[f]),
        bool(z[who[f]] > z[other[f]])) for f in first}


def _between(xy: FloatArray, vxy: FloatArray, pairs: NDArray[np.intp], m: int, step: float
             ) -> tuple[FloatArray, FloatArray]:
    """For each pair of flat sample indices (vehicle * m + sample) of one instant: the
    smallest horizontal distance of the two from the previous sample to the next, on the
    cubic each sample's position and velocity fix (`BETWEEN` points a step), and when
    (s)."""
    a, b = pairs[:, 0], pairs[:, 1]
    k = a % m
    s = np.linspace(0.0, 1.0, BETWEEN + 1)
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    gaps = np.full(len(pairs), np.inf)
    at = np.zeros(len(pairs))
    for lo in (-1, 0):  # the step before the sample, and the one after
        i0 = np.clip(k + lo, 0, m - 1) - k
        i1 = np.clip(k + lo + 1, 0, m - 1) - k
        r0, r1 = xy[a + i0] - xy[b + i0], xy[a + i1] - xy[b + i1]
        u0, u1 = vxy[a + i0] - vxy[b + i0], vxy[a + i1] - vxy[b + i1]
        r = (h00[:, None, None] * r0 + h10[:, None, None] * step * u0
             + h01[:, None, None] * r1 + h11[:, None, None] * step * u1)  # (S, C, 2)
        d = np.linalg.norm(r, axis=2)
        j = np.argmin(d, axis=0)
        low = d[j, np.arange(len(pairs))]
        better = low < gaps
        gaps[better] = low[better]
        at[better] = ((k + i0)[better] + s[j[better]] * (i1 - i0)[better]) * step
    return gaps, at


def stacked_columns(plan: Plan, clearance: float, rate: float = COLUMN_RATE_HZ
                    ) -> tuple[str, str, float, float] | None:
    """The pair of vehicles the plan brings closest horizontally (`column_conflicts`), as
    (lower, upper, horizontal distance m, flight time s), or None when no columns meet."""
    conflicts = column_conflicts(plan, clearance, rate)
    if not conflicts:
        return None
    vid, c = min(conflicts.items(), key=lambda item: (item[1].gap, item[1].t))
    return (vid, c.other, c.gap, c.t) if not c.above else (c.other, vid, c.gap, c.t)


async def set_failsafe(v: VehicleStatus, delay: float, hover: bool, context: FlightContext, *,
                       why: str = "") -> None:
    """Read `v`'s failsafe, set it to land after `delay` s, or with `hover` to stay hovering
    (see the module; its autopilot says which parameters: `Autopilot.failsafe_settings`),
    keep what it answered in `v.failsafe`, what it had in `v.failsafe_before`, and say it in
    a `failsafe` event (with `why`). A parameter that cannot be read or set is
    `FailsafeNotSet` naming it when the fleet option `failsafe` is `set`, else an event: then
    what the vehicle does without the station is what its own parameters say."""
    emit = context.emit
    link = v.linked
    kind = v.autopilot
    name = next(iter(kind.failsafe_params))
    try:
        before: dict[str, float] = {}
        for name, k in kind.failsafe_params.items():
            before[name] = await read_param(link, name, k)
        settings = kind.failsafe_settings(before, delay, hover=hover)
        after = dict(before)
        for name, value in settings.items():
            after[name] = await set_param(link, name, kind.failsafe_params[name], value)
    except ParamError as exc:
        if context.options.failsafe == "set":
            raise FailsafeNotSet(v.id, name, f"{exc}: what it does without the station is "
                                             f"not known, so it is not armed (fleet option "
                                             f"failsafe: try flies it anyway)") from None
        emit(v.id, EventKind.FAILSAFE, f"not set ({exc}): without the station it does what "
                                       f"its own parameters say")
        return
    v.failsafe = kind.failsafe(after)
    v.failsafe_before, v.failsafe_set = before, after
    changed = [f"{name} {before[name]:g} -> {after[name]:g}" for name in settings
               if before[name] != after[name]]
    emit(v.id, EventKind.FAILSAFE, f"without the station: {v.failsafe.text()}"
                                   + (f" ({why})" if why else "")
                                   + (f" (set {', '.join(changed)})" if changed else ""))


async def restore_failsafe(v: VehicleStatus, context: FlightContext) -> None:
    """Put back the failsafe parameters `set_failsafe` changed on `v` (the values it read),
    after the flight, and say it; a vehicle still following setpoints keeps the flight's
    (the station may yet stop streaming to it)."""
    emit = context.emit
    before, after = v.failsafe_before, v.failsafe_set
    if before is None or after is None or v.link is None:
        return
    changed = {name: value for name, value in before.items() if value != after[name]}
    if not changed:
        return
    kind = v.autopilot
    tel = v.link.telemetry
    if tel.armed and tel.mode == kind.follow_mode:
        emit(v.id, EventKind.FAILSAFE, f"not restored: still in {kind.follow_mode.name}, it "
                                       f"keeps the flight's failsafe ({v.failsafe.text()})")
        return
    done = []
    try:
        for name, value in changed.items():
            await set_param(v.link, name, kind.failsafe_params[name], value)
            done.append(f"{name} {after[name]:g} -> {value:g}")
    except ParamError as exc:
        emit(v.id, EventKind.FAILSAFE, f"not restored ({exc}); restored: "
                                       f"{', '.join(done) or 'nothing'}")
        return
    v.failsafe = kind.failsafe(before)
    v.failsafe_before = v.failsafe_set = None
    emit(v.id, EventKind.FAILSAFE, f"restored after the flight: {', '.join(done)}")


def failsafe_record(failsafe: LinkLossFailsafe) -> dict[str, Any]:
    """What a vehicle does without the station, for the flight record."""
    def finite(x: float) -> float | None:  # ArduPilot's hold lasts for good: no number
        return x if math.isfinite(x) else None

    return {"loss_timeout": finite(failsafe.loss_timeout),
            "action_delay": finite(failsafe.action_delay), "action": failsafe.effective}
