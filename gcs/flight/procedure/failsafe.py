"""Each vehicle's own link-loss failsafe, read and set before arming, and told.

When the ground station is gone (its process killed, its computer or radio dead), no
setpoint arrives and each PX4 vehicle flies its offboard-loss failsafe
(`gcs.px4.OffboardLossFailsafe`): COM_OF_LOSS_T after the last setpoint it leaves OFFBOARD
and holds in Position for COM_FAIL_ACT_T, then takes COM_OBL_RC_ACT (Position, Altitude and
Manual need RC: without it PX4 lands). Before arming, `set_failsafe` reads the three
parameters (PARAM_REQUEST_READ) and sets:

- COM_OBL_RC_ACT per vehicle from the plan (`failsafe_actions`): Hold for a vehicle whose
  column ever comes within R of another's horizontally (`column_conflicts`: no autopilot
  failsafe moves a vehicle sideways, so landing two such vehicles straight down brings them
  that close; hovering where the station left them keeps the plan's separation in 3D, and
  the operator lands them by plan: `fleetplan fleet land --plan`), Land for the others
  (Return climbs and crosses the others' paths);
- COM_FAIL_ACT_T staggered by altitude layer (`layer_delays`): the lowest layer lands after
  PX4's default 5 s, each layer above only once the one below has had time to reach the
  ground, so no vehicle descends onto one still hovering below it;
- COM_OF_LOSS_T is kept (PX4's 1 s unless the operator chose otherwise).

Every value is read back from the vehicle's PARAM_VALUE; `v.failsafe` then holds what the
vehicle does (the flight's predictions of a lost vehicle use it), and a `failsafe` event says
it. A parameter that cannot be read or set refuses the flight (`FailsafeNotSet`) unless the
fleet option `failsafe` is `try`. After the flight `restore_failsafe` puts back the values
read.
"""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from gcs import px4
from gcs.errors import FailsafeNotSet
from gcs.flight.link.link import VehicleLink
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.phases import EventKind
from gcs.wire import PARAM_TYPES, decode_param, encode_param
from planner import Plan

__all__ = ["FAILSAFE_PARAMS", "LAYER_GAP_M", "ColumnConflict", "ParamError", "column_conflicts",
           "failsafe_actions", "layer_delays", "read_param", "restore_failsafe",
           "set_failsafe", "set_param", "stacked_columns"]

#: The failsafe's parameters and their PX4 types.
FAILSAFE_PARAMS = {"COM_OF_LOSS_T": "f", "COM_FAIL_ACT_T": "f", "COM_OBL_RC_ACT": "i"}
#: Vehicles whose planned heights differ by less than this (m) are one layer.
LAYER_GAP_M = 0.3
#: A layer above starts down this long (s) after the one below should be on the ground.
LAYER_SETTLE_S = 1.0
#: COM_FAIL_ACT_T's largest value (PX4's documented maximum, s).
ACTION_DELAY_MAX = 25.0
#: Columns closer than R by more than this (m) meet (`column_conflicts`): a straight-down
#: landing of the two keeps at least R less this.
STACKED_TOLERANCE = 0.05
#: The plan's samples per second the columns are compared at.
COLUMN_RATE_HZ = 10.0
#: Tries of one parameter read or write, and the wait for each answer (s).
TRIES = 3
ANSWER_S = 1.0


class ParamError(Exception):
    """A parameter was not answered or not taken (the reason in words)."""


async def _exchange(link: VehicleLink, name: str, send: Any) -> Any:
    """Send `send()`'s message until a PARAM_VALUE for `name` answers; that message."""
    answers: asyncio.Queue[Any] = asyncio.Queue()

    def on_message(_link: VehicleLink, msg: Any, _now: float) -> None:
        if msg.get_type() == "PARAM_VALUE" and _param_id(msg) == name:
            answers.put_nowait(msg)

    link.listeners.append(on_message)
    try:
        for _ in range(TRIES):
            link.send(send())
            deadline = time.monotonic() + ANSWER_S
            while (left := deadline - time.monotonic()) > 0:
                try:
                    return await asyncio.wait_for(answers.get(), left)
                except TimeoutError:
                    break
        raise ParamError(f"{name} not answered after {TRIES} tries")
    finally:
        link.listeners.remove(on_message)


def _param_id(msg: Any) -> str:
    raw = msg.param_id
    text = raw.decode(errors="replace") if isinstance(raw, bytes) else str(raw)
    return text.rstrip("\x00")


async def read_param(link: VehicleLink, name: str, kind: str) -> float:
    """The vehicle's value of parameter `name` (type `kind`: "f" or "i")."""
    msg = await _exchange(link, name, lambda: link.mav.param_request_read_encode(
        link.system_id, link.component_id, name.encode(), -1))
    return decode_param(kind, msg.param_value)


async def set_param(link: VehicleLink, name: str, kind: str, value: float) -> float:
    """Set parameter `name` to `value`; the value the vehicle answers with (`ParamError`
    when it keeps another)."""
    msg = await _exchange(link, name, lambda: link.mav.param_set_encode(
        link.system_id, link.component_id, name.encode(), encode_param(kind, value),
        PARAM_TYPES[kind]))
    got = decode_param(kind, msg.param_value)
    if not math.isclose(got, value, rel_tol=1e-6, abs_tol=1e-6):
        raise ParamError(f"{name} set to {value:g} but the vehicle keeps {got:g}")
    return got


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
    delay = px4.COM_FAIL_ACT_T_S
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
    landing bring them that close. Sampled at `rate` Hz; one k-d tree over every sample,
    the sample index as a third coordinate spaced wider than the reach, so that only
    pairs of one instant are found (no loop over samples or pairs)."""
    scenario = plan.scenario
    times = np.arange(0.0, scenario.horizon + 1e-9, 1.0 / rate)
    p = plan.sample(times).position  # (N, T, 3)
    n, m = p.shape[:2]
    reach = clearance - STACKED_TOLERANCE
    if n < 2 or reach <= 0:
        return {}
    scale = np.asarray(scenario.separation_scale, dtype=float)[:2]
    k = np.broadcast_to(np.arange(m, dtype=float), (n, m))
    points = np.concatenate([p[:, :, :2] / scale, (2.0 * reach + 1.0) * k[:, :, None]],
                            axis=2).reshape(-1, 3)
    pairs = cKDTree(points).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return {}
    gaps = np.linalg.norm(points[pairs[:, 0], :2] - points[pairs[:, 1], :2], axis=1)
    who = np.concatenate([pairs[:, 0], pairs[:, 1]])  # flat index: vehicle * m + sample
    other = np.concatenate([pairs[:, 1], pairs[:, 0]])
    gap = np.concatenate([gaps, gaps])
    order = np.lexsort((who % m, gap, who // m))  # per vehicle: smallest gap, then earliest
    first = order[np.unique(who[order] // m, return_index=True)[1]]
    ids = scenario.ids
    z = p[:, :, 2].reshape(-1)
    return {ids[int(who[f] // m)]: ColumnConflict(
        ids[int(other[f] // m)], float(gap[f]), float(times[int(who[f] % m)]),
        bool(z[who[f]] > z[other[f]])) for f in first}


def stacked_columns(plan: Plan, clearance: float, rate: float = COLUMN_RATE_HZ
                    ) -> tuple[str, str, float, float] | None:
    """The pair of vehicles the plan brings closest horizontally (`column_conflicts`), as
    (lower, upper, horizontal distance m, flight time s), or None when no columns meet."""
    conflicts = column_conflicts(plan, clearance, rate)
    if not conflicts:
        return None
    vid, c = min(conflicts.items(), key=lambda item: (item[1].gap, item[1].t))
    return (vid, c.other, c.gap, c.t) if not c.above else (c.other, vid, c.gap, c.t)


def failsafe_actions(ids: list[str], conflicts: dict[str, ColumnConflict]) -> dict[str, int]:
    """COM_OBL_RC_ACT per vehicle: Hold for a vehicle whose column meets another's
    (`conflicts`, from `column_conflicts`: landing straight down would bring them closer than
    R; hovering where the station left them keeps the plan's 3D separation), Land for the
    others (their straight descents keep clear of every vehicle, hovering or landing)."""
    return {vid: px4.OBL_HOLD if vid in conflicts else px4.OBL_LAND for vid in ids}


async def set_failsafe(v: VehicleStatus, delay: float, action: int, emit: Emit, *,
                       required: bool = True, why: str = "") -> None:
    """Read `v`'s failsafe, set it to take `action` (COM_OBL_RC_ACT) after `delay` s (see
    the module), keep what it answered in `v.failsafe` and what it had in
    `v.failsafe_before`, and say it in a `failsafe` event (with `why`, the reason for its
    action). A parameter that cannot be read or set is `FailsafeNotSet` naming it when
    `required` (the fleet option `failsafe: set`), else an event: then what the vehicle does
    without the station is what its own parameters say."""
    link = v.linked
    name = "COM_OF_LOSS_T"
    try:
        before: dict[str, float] = {}
        for name, kind in FAILSAFE_PARAMS.items():
            before[name] = await read_param(link, name, kind)
        name = "COM_OBL_RC_ACT"
        got = before[name]
        if got != action:
            got = await set_param(link, name, "i", action)
        name = "COM_FAIL_ACT_T"
        wait = before[name]
        if not math.isclose(wait, delay, abs_tol=1e-3):
            wait = await set_param(link, name, "f", delay)
    except ParamError as exc:
        if required:
            raise FailsafeNotSet(v.id, name, f"{exc}: what it does without the station is "
                                             f"not known, so it is not armed (fleet option "
                                             f"failsafe: try flies it anyway)") from None
        emit(v.id, EventKind.FAILSAFE, f"not set ({exc}): without the station it does what "
                                       f"its own parameters say")
        return
    v.failsafe_before = before
    v.failsafe = px4.OffboardLossFailsafe(before["COM_OF_LOSS_T"], wait, int(got))
    changed = [f"{name} {before[name]:g} -> {after:g}" for name, after in
               (("COM_OBL_RC_ACT", got), ("COM_FAIL_ACT_T", wait)) if before[name] != after]
    emit(v.id, EventKind.FAILSAFE, f"without the station: {v.failsafe.text()}"
                                   + (f" ({why})" if why else "")
                                   + (f" (set {', '.join(changed)})" if changed else ""))


async def restore_failsafe(v: VehicleStatus, emit: Emit) -> None:
    """Put back the failsafe parameters `set_failsafe` changed on `v` (the values it read),
    after the flight, and say it; a vehicle still in OFFBOARD keeps the flight's (the
    station may yet stop streaming to it)."""
    before = v.failsafe_before
    if before is None or v.link is None:
        return
    changed = {name: value for name, value in before.items()
               if name != "COM_OF_LOSS_T" and not math.isclose(
                   value, _flight_value(v.failsafe, name), abs_tol=1e-3)}
    if not changed:
        return
    tel = v.link.telemetry
    if tel.armed and tel.mode == px4.OFFBOARD:
        emit(v.id, EventKind.FAILSAFE, "not restored: still in OFFBOARD, it keeps the "
                                       f"flight's failsafe ({v.failsafe.text()})")
        return
    done = []
    try:
        for name, value in changed.items():
            await set_param(v.link, name, FAILSAFE_PARAMS[name], value)
            done.append(f"{name} {_flight_value(v.failsafe, name):g} -> {value:g}")
    except ParamError as exc:
        emit(v.id, EventKind.FAILSAFE, f"not restored ({exc}); restored: "
                                       f"{', '.join(done) or 'nothing'}")
        return
    v.failsafe_before = None
    v.failsafe = px4.OffboardLossFailsafe(before["COM_OF_LOSS_T"], before["COM_FAIL_ACT_T"],
                                          int(before["COM_OBL_RC_ACT"]))
    emit(v.id, EventKind.FAILSAFE, f"restored after the flight: {', '.join(done)}")


def _flight_value(failsafe: px4.OffboardLossFailsafe, name: str) -> float:
    """The value of parameter `name` that `failsafe` stands for."""
    return {"COM_OF_LOSS_T": failsafe.loss_timeout, "COM_FAIL_ACT_T": failsafe.action_delay,
            "COM_OBL_RC_ACT": float(failsafe.action)}[name]
