"""Each vehicle's own link-loss failsafe, read and set before arming, and told.

When the ground station is gone (its process killed, its computer or radio dead), no
setpoint arrives and each PX4 vehicle flies its offboard-loss failsafe
(`gcs.autopilot.px4.OffboardLossFailsafe`): COM_OF_LOSS_T after the last setpoint it leaves OFFBOARD
and holds in Position for COM_FAIL_ACT_T, then takes COM_OBL_RC_ACT (Position, Altitude and
Manual need RC: without it PX4 lands). Before arming, `set_failsafe` reads the three
parameters (PARAM_REQUEST_READ) and sets:

- COM_OBL_RC_ACT to Land: a fleet landing straight down from where it held is what can be
  told in advance (Return climbs and crosses the others' paths, Hold never comes down);
- COM_FAIL_ACT_T staggered by altitude layer (`layer_delays`): the lowest layer lands after
  PX4's default 5 s, each layer above only once the one below has had time to reach the
  ground, so no vehicle descends onto one still hovering below it;
- COM_OF_LOSS_T is kept (PX4's 1 s unless the operator chose otherwise).

An ArduCopter's counterparts (`gcs.autopilot.ardupilot`): `FS_GCS_ENABLE` set to Land and
`FS_GCS_TIMEOUT` staggered the same way; `GUID_TIMEOUT` kept. Which parameters, and what they
mean, is the vehicle's `Autopilot`'s to say.

Every value is read back from the vehicle's PARAM_VALUE; `v.failsafe` then holds what the
vehicle does (the flight's predictions of a lost vehicle use it), and a `failsafe` event says
it. `stacked_columns` finds where the plan puts two vehicles closer than R horizontally: a
station lost then lands them that close (no autopilot failsafe moves a vehicle sideways).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from gcs.flight.procedure.params import ParamError, read_param, set_param
from gcs.flight.procedure.vehicle import Emit, VehicleStatus
from gcs.phases import EventKind
from planner import Plan

__all__ = ["LAYER_BASE_DELAY_S", "LAYER_GAP_M", "ParamError", "layer_delays", "read_param",
           "set_failsafe", "set_param", "stacked_columns"]

#: The lowest layer's delay (s): the default of both autopilots' failsafe delays (PX4's
#: COM_FAIL_ACT_T, ArduPilot's FS_GCS_TIMEOUT).
LAYER_BASE_DELAY_S = 5.0
#: Vehicles whose planned heights differ by less than this (m) are one layer.
LAYER_GAP_M = 0.3
#: A layer above starts down this long (s) after the one below should be on the ground.
LAYER_SETTLE_S = 1.0
#: COM_FAIL_ACT_T's largest value (PX4's documented maximum, s).
ACTION_DELAY_MAX = 25.0
#: Columns closer than R by more than this (m) are told as stacked (`stacked_columns`).
STACKED_TOLERANCE = 0.05


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


def stacked_columns(plan: Plan, clearance: float, rate: float = 5.0
                    ) -> tuple[str, str, float, float] | None:
    """The pair of vehicles the plan brings closest horizontally, below `clearance` less
    `STACKED_TOLERANCE`, as (lower, upper, horizontal distance m, flight time s), or None: a
    fleet that loses its station there lands them that close. Sampled at `rate` Hz, the
    close pairs of each sample found by a k-d tree (a large fleet is not paired whole)."""
    times = np.arange(0.0, plan.scenario.horizon + 1e-9, 1.0 / rate)
    p = plan.sample(times).position  # (N, T, 3)
    if len(p) < 2:
        return None
    reach = clearance - STACKED_TOLERANCE
    best: tuple[float, int, int, int] | None = None
    for k in range(len(times)):
        xy = p[:, k, :2]
        pairs = cKDTree(xy).query_pairs(reach, output_type="ndarray")
        if len(pairs) == 0:
            continue
        gaps = np.linalg.norm(xy[pairs[:, 0]] - xy[pairs[:, 1]], axis=1)
        n = int(np.argmin(gaps))
        if best is None or gaps[n] < best[0]:
            best = (float(gaps[n]), int(pairs[n, 0]), int(pairs[n, 1]), k)
    if best is None:
        return None
    gap, a, b, k = best
    lower, upper = (a, b) if p[a, k, 2] <= p[b, k, 2] else (b, a)
    ids = plan.scenario.ids
    return ids[lower], ids[upper], gap, float(times[k])


async def set_failsafe(v: VehicleStatus, delay: float, emit: Emit) -> None:
    """Read `v`'s failsafe, set it to land after `delay` s (see the module; its autopilot says
    which parameters: `Autopilot.failsafe_settings`), keep what it answered in `v.failsafe`
    and say it (a `failsafe` event, also when it cannot be read or set: then what the vehicle
    does without the station is not known)."""
    link = v.linked
    kind = v.autopilot
    try:
        before = {name: await read_param(link, name, k)
                  for name, k in kind.failsafe_params.items()}
        settings = kind.failsafe_settings(before, delay)
        after = dict(before)
        for name, value in settings.items():
            after[name] = await set_param(link, name, kind.failsafe_params[name], value)
    except ParamError as exc:
        emit(v.id, EventKind.FAILSAFE, f"not set ({exc}): without the station it does what "
                                       f"its own parameters say")
        return
    v.failsafe = kind.failsafe(after)
    changed = [f"{name} {before[name]:g} -> {after[name]:g}" for name in settings
               if before[name] != after[name]]
    emit(v.id, EventKind.FAILSAFE, f"without the station: {v.failsafe.text()}"
                                   + (f" (set {', '.join(changed)})" if changed else ""))
