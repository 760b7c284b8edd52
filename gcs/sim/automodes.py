"""PX4's AUTO.TAKEOFF and AUTO.RTL on a mock vehicle, as PX4's navigator flies them.

AUTO.TAKEOFF (MAV_CMD_NAV_TAKEOFF, or the mode itself) climbs straight up to its altitude, then
holds there in AUTO.LOITER (Hold). The altitude is PX4's `Takeoff::set_takeoff_position`: the
command's param7 (AMSL) when given, but never below MIS_TAKEOFF_ALT above home ("Using minimum
takeoff altitude: 2.50 m") nor below where the vehicle already is ("Already higher than takeoff
altitude"); the mode entered without the command uses MIS_TAKEOFF_ALT. A vehicle in the mode
but disarmed takes off once armed.

AUTO.RTL climbs to RTL_RETURN_ALT above home (if lower), flies over home at that height, then
lands (RTL_CONE_ANG and RTL_DESCEND_ALT are not modelled: PX4's cone can lower the return
altitude near home, and it descends to RTL_DESCEND_ALT before landing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from gcs import frames
from gcs.autopilot import px4
from gcs.sim.config import MockConfig
from gcs.sim.model import FleetModel
from gcs.wire import mavlink

__all__ = ["ALTITUDE_REACHED_M", "HOME_REACHED_M", "AutoHost", "AutoState", "enter",
           "takeoff_height", "tick"]

#: A takeoff or RTL climb is done within this of its altitude (m).
ALTITUDE_REACHED_M = 0.15
#: RTL starts its landing within this horizontal distance of home (m).
HOME_REACHED_M = 0.2


@dataclass
class AutoState:
    """Where the current AUTO mode is going (NED, m; heights above home)."""

    takeoff_height: float | None = None
    """The takeoff's height above home (None: MIS_TAKEOFF_ALT, decided on entry)."""
    rtl_phase: str = ""
    """"climb", "return" or "land" during AUTO.RTL."""
    rtl_height: float = 0.0


class AutoHost(Protocol):
    """What the AUTO modes need of a vehicle (`gcs.sim.core.VehicleCore` has it)."""

    index: int
    auto: AutoState
    origin: frames.Geodetic

    @property
    def mode(self) -> px4.Px4Mode: ...
    @property
    def config(self) -> MockConfig: ...
    @property
    def model(self) -> FleetModel: ...
    def set_mode(self, mode: px4.Px4Mode) -> None: ...
    def statustext(self, severity: int, text: str) -> None: ...


def takeoff_height(v: AutoHost, amsl: float) -> float:
    """The height above home a MAV_CMD_NAV_TAKEOFF to `amsl` (param7; NaN: none) climbs to,
    saying what PX4 says when it changes it."""
    minimum = float(v.config.takeoff_altitude)
    height_now = -float(v.model.position[v.index, 2])
    if math.isfinite(amsl):
        height = amsl - v.origin.alt
        if height < minimum - 0.1:
            v.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                         f"Using minimum takeoff altitude: {minimum:.2f} m")
        height = max(height, minimum)
    else:
        v.statustext(mavlink.MAV_SEVERITY_INFO,
                     f"Using minimum takeoff altitude: {minimum:.2f} m")
        height = minimum
    if height < height_now:
        v.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Already higher than takeoff altitude")
        height = height_now
    return height


def enter(v: AutoHost, mode: px4.Px4Mode) -> None:
    """Start `mode` (AUTO.TAKEOFF or AUTO.RTL) from where the vehicle is."""
    i = v.index
    p = v.model.position[i]
    if mode == px4.TAKEOFF:
        if v.auto.takeoff_height is None:
            v.auto.takeoff_height = takeoff_height(v, math.nan)
        v.model.hold(i, np.array([p[0], p[1], -v.auto.takeoff_height]))
    elif mode == px4.RTL:
        height = -float(p[2])
        v.auto.rtl_height = max(height, float(v.config.rtl_return_altitude))
        v.auto.rtl_phase = "climb" if v.auto.rtl_height - height > ALTITUDE_REACHED_M else "return"
        target = (p[0], p[1]) if v.auto.rtl_phase == "climb" else (0.0, 0.0)
        v.model.hold(i, np.array([target[0], target[1], -v.auto.rtl_height]))


def tick(v: AutoHost, now: float) -> None:
    """Advance AUTO.TAKEOFF or AUTO.RTL (called every mock tick while armed)."""
    i = v.index
    p = v.model.position[i]
    if v.mode == px4.TAKEOFF and v.auto.takeoff_height is not None:
        if abs(-p[2] - v.auto.takeoff_height) < ALTITUDE_REACHED_M:
            target = v.model.position_sp[i].copy()
            v.auto.takeoff_height = None
            v.set_mode(px4.HOLD)
            v.model.hold(i, target)  # hold the takeoff point, not where it crossed it
    elif v.mode == px4.RTL:
        phase = v.auto.rtl_phase
        if phase == "climb" and abs(-p[2] - v.auto.rtl_height) < ALTITUDE_REACHED_M:
            v.auto.rtl_phase = "return"
            v.model.hold(i, np.array([0.0, 0.0, -v.auto.rtl_height]))
        elif phase == "return" and math.hypot(p[0], p[1]) < HOME_REACHED_M:
            v.auto.rtl_phase = "land"
            v.model.descend(i, v.config.land_speed)
