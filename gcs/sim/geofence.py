"""The geofence of a mock vehicle, checked and acted on as PX4's navigator and commander do.

The fence is what the mission protocol stored (`gcs.sim.missions`, mission_type 1), turned into
the vehicle's LOCAL_NED once per upload; PX4's rule (`Geofence::isInsidePolygonOrCircle`): the
vehicle must be inside at least one inclusion polygon or circle (when there are any) and outside
every exclusion one; GF_MAX_HOR_DIST and GF_MAX_VER_DIST (0: off) bound the distance from home
and the height above it. Checked every `CHECK_INTERVAL_S` on the reported position (PX4 also
predicts the breach from the braking distance, GF_PREDICT; the mock does not).

On a breach while armed it says PX4's "Approaching on Geofence" once and does GF_ACTION: 0
nothing, 1 the warning only, 2 Hold (at the last point inside the fence), 3 RTL, 4 flight
termination, 5 Land. SYS_STATUS reports the geofence unhealthy while it is breached.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from gcs import frames
from gcs.autopilot import px4
from gcs.geofence import shape_contains
from gcs.sim.config import MockConfig
from gcs.sim.missions import FenceShape
from gcs.sim.model import FleetModel
from gcs.sim.params import VehicleParams
from gcs.wire import mavlink

__all__ = ["CHECK_INTERVAL_S", "FenceHost", "Geofence", "LocalShape", "check"]

#: How often the fence is checked (s).
CHECK_INTERVAL_S = 0.1


@dataclass(frozen=True)
class LocalShape:
    """A fence shape in the vehicle's LOCAL_NED (x north, y east, m)."""

    inclusion: bool
    points: np.ndarray
    """(k, 2) polygon vertices, or (1, 2) the circle's centre."""
    radius: float | None

    def contains(self, xy: np.ndarray) -> bool:
        """Whether the horizontal point `xy` is inside (even-odd rule for polygons)."""
        return shape_contains(self.points, self.radius, xy)


class Geofence:
    """One vehicle's fence in its LOCAL_NED, and where it last was inside it."""

    def __init__(self, origin: frames.Geodetic) -> None:
        self.origin = origin
        self.shapes: list[LocalShape] = []
        self.breached = False
        self.last_inside: np.ndarray | None = None
        self.next_check = 0.0
        """Mock time of the next check."""

    def load(self, shapes: list[FenceShape]) -> None:
        """Take the stored fence (lat/lon shapes) into LOCAL_NED."""
        local = []
        for shape in shapes:
            points = []
            for lat, lon in shape.vertices:
                enu = frames.geodetic_to_enu(frames.Geodetic(lat, lon, self.origin.alt),
                                             self.origin)
                north, east, _down = frames.world_vector_to_ned(enu)
                points.append((north, east))
            local.append(LocalShape(shape.inclusion, np.array(points, dtype=float),
                                    shape.radius))
        self.shapes = local

    def inside(self, p_ned: np.ndarray, max_horizontal: float, max_vertical: float) -> bool:
        """PX4's rule for the position `p_ned` (a limit <= 0 is off)."""
        xy = p_ned[:2]
        if max_horizontal > 0 and np.hypot(*xy) > max_horizontal:
            return False
        if max_vertical > 0 and -p_ned[2] > max_vertical:
            return False
        inclusions = [s for s in self.shapes if s.inclusion]
        if inclusions and not any(s.contains(xy) for s in inclusions):
            return False
        return not any(s.contains(xy) for s in self.shapes if not s.inclusion)

    @property
    def active(self) -> bool:
        return bool(self.shapes)


class FenceHost(Protocol):
    """What the fence check needs of a vehicle (`gcs.sim.vehicle.MockVehicle` has it)."""

    index: int
    geofence: Geofence
    params: VehicleParams
    fence_breached: bool
    terminated: bool

    @property
    def armed(self) -> bool: ...
    @property
    def config(self) -> MockConfig: ...
    @property
    def model(self) -> FleetModel: ...
    @property
    def position_ned(self) -> np.ndarray: ...
    def set_mode(self, mode: px4.Px4Mode) -> None: ...
    def disarm(self, why: str) -> None: ...
    def event(self, what: str) -> None: ...
    def statustext(self, severity: int, text: str) -> None: ...


def check(v: FenceHost, now: float) -> None:
    """Check `v`'s fence (every `CHECK_INTERVAL_S`) and act on a new breach."""
    fence = v.geofence
    if now < fence.next_check:
        return
    fence.next_check = now + CHECK_INTERVAL_S
    max_h = v.params.value("GF_MAX_HOR_DIST")
    max_v = v.params.value("GF_MAX_VER_DIST")
    if not fence.active and max_h <= 0 and max_v <= 0:
        fence.breached = v.fence_breached = False
        return
    p = v.position_ned
    if fence.inside(p, max_h, max_v):
        fence.breached = v.fence_breached = False
        fence.last_inside = p
        return
    new = not fence.breached
    fence.breached = v.fence_breached = True
    if not (new and v.armed):
        return
    action = int(v.config.geofence_action)
    if action == 0:
        return
    v.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Approaching on Geofence")
    v.event(f"geofence breached (GF_ACTION {action})")
    if action == 2:
        v.set_mode(px4.HOLD)
        if fence.last_inside is not None:
            v.model.hold(v.index, fence.last_inside)
    elif action == 3:
        v.set_mode(px4.RTL)
    elif action == 4:
        v.terminated = True
        v.disarm("flight termination")
    elif action == 5:
        v.set_mode(px4.LAND)
