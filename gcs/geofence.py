"""The geofence a flight gives every vehicle, built from the plan's scenario (numbers only).

PX4 fences are horizontal shapes in latitude/longitude (the mission protocol's FENCE list):
the workspace's horizontal rectangle becomes one inclusion polygon, and every obstacle that
stands on the ground (its bottom at or below the workspace floor + `GROUND_TOLERANCE`) an
exclusion: a box's footprint or a prism's polygon as an exclusion polygon, a cylinder as an
exclusion circle. An obstacle that does not reach the ground (a net, a shelf's top board)
cannot be a PX4 fence: a horizontal exclusion would forbid the air under it too; it is listed
in `WorldFence.not_fenced` for the flight to say so. The obstacle solid itself is fenced
(no clearance added): the plan keeps its clearance from it, the fence catches a vehicle that
left its plan.

`WorldFence` is in the planner's world frame (ENU, m); `fence_items` places it on the Earth
for one vehicle (`gcs.frames.world_to_geodetic`) as MISSION_ITEM_INT numbers, and
`gcs.export.qgc_plan` writes it as a QGroundControl `.plan` file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gcs import frames
from gcs.wire import mavlink

__all__ = ["GROUND_TOLERANCE", "FenceItem", "WorldFence", "WorldShape", "build_fence",
           "fence_items", "item_mismatch", "place_shapes", "shape_contains"]

#: An obstacle whose bottom is at most this far above the workspace floor stands on the
#: ground (m): a vehicle cannot pass under it.
GROUND_TOLERANCE = 0.05

_m = mavlink
POLYGON_INCLUSION = _m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
POLYGON_EXCLUSION = _m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CIRCLE_INCLUSION = _m.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
CIRCLE_EXCLUSION = _m.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION


@dataclass(frozen=True)
class WorldShape:
    """One fence shape in the world frame: a polygon ((k, 2) x, y vertices) or a circle (one
    centre and `radius`), inclusion or exclusion; `source` names what it fences."""

    inclusion: bool
    points: np.ndarray
    radius: float | None
    source: str
    """``workspace`` or the obstacle's id."""

    def contains(self, xy: ArrayLike) -> bool:
        """Whether the horizontal point `xy` is inside the shape."""
        return shape_contains(self.points, self.radius, xy)


def shape_contains(points: np.ndarray, radius: float | None, xy: ArrayLike) -> bool:
    """Whether the horizontal point `xy` is inside a circle (centre `points[0]`, `radius`) or
    a polygon (`points` (k, 2), even-odd rule, as PX4's `Geofence::insidePolygon`)."""
    p = np.asarray(xy, dtype=float)
    if radius is not None:
        return bool(np.hypot(*(p - points[0])) <= radius)
    inside = False
    for (x1, y1), (x2, y2) in zip(points, np.roll(points, -1, axis=0), strict=True):
        if (y1 > p[1]) != (y2 > p[1]) and p[0] < x1 + (p[1] - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


@dataclass(frozen=True)
class WorldFence:
    """A scenario's fence in the world frame, and the obstacles it cannot express."""

    shapes: tuple[WorldShape, ...]
    not_fenced: tuple[str, ...]
    """Ids of obstacles that do not reach the ground (no PX4 fence can hold them)."""

    def breaches(self, xy: ArrayLike) -> list[str]:
        """What the horizontal point `xy` breaks: ``workspace`` when outside the inclusion,
        and the ids of the exclusions it is inside."""
        out = [s.source for s in self.shapes if s.inclusion and not s.contains(xy)]
        return out + [s.source for s in self.shapes if not s.inclusion and s.contains(xy)]


@dataclass(frozen=True)
class FenceItem:
    """One MISSION_ITEM_INT of a FENCE list (frame MAV_FRAME_GLOBAL): the command, param1
    (a polygon's vertex count, a circle's radius in m) and x/y latitude/longitude in degE7."""

    command: int
    param1: float
    x: int
    y: int


def build_fence(scenario: Mapping[str, Any],
                ground_tolerance: float = GROUND_TOLERANCE) -> WorldFence:
    """The fence of a scenario dict (the scenario JSON, `Scenario.to_dict()`): the workspace
    rectangle as inclusion, obstacles on the ground as exclusions (see the module)."""
    limits = scenario["limits"]
    lo = np.asarray(limits["position_min"], dtype=float)
    hi = np.asarray(limits["position_max"], dtype=float)
    floor = float(lo[2])
    shapes = [WorldShape(True, np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]],
                                         [lo[0], hi[1]]]), None, "workspace")]
    not_fenced: list[str] = []
    for obstacle in scenario.get("obstacles", []) or []:
        shape, bottom = _obstacle_shape(obstacle)
        if bottom > floor + ground_tolerance:
            not_fenced.append(str(obstacle.get("id")))
        else:
            shapes.append(shape)
    return WorldFence(tuple(shapes), tuple(not_fenced))


def _obstacle_shape(obstacle: Mapping[str, Any]) -> tuple[WorldShape, float]:
    """An obstacle's exclusion shape and the height of its bottom."""
    oid = str(obstacle.get("id"))
    if "box" in obstacle:
        lo = np.asarray(obstacle["box"]["min"], dtype=float)
        hi = np.asarray(obstacle["box"]["max"], dtype=float)
        pts = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        return WorldShape(False, pts, None, oid), float(lo[2])
    if "cylinder" in obstacle:
        cyl = obstacle["cylinder"]
        centre = np.asarray(cyl["center"], dtype=float).reshape(1, 2)
        return (WorldShape(False, centre, float(cyl["radius"]), oid),
                float(min(cyl["z"])))
    if "prism" in obstacle:
        prism = obstacle["prism"]
        pts = np.asarray(prism["polygon"], dtype=float).reshape(-1, 2)
        return WorldShape(False, pts, None, oid), float(min(prism["z"]))
    raise ValueError(f"obstacle {oid!r}: neither box, cylinder nor prism")


def place_shapes(fence: WorldFence, home_world: ArrayLike,
                 origin: frames.Geodetic) -> list[tuple[WorldShape, np.ndarray]]:
    """Every shape with its points as (k, 2) latitude, longitude (degrees), for a vehicle
    whose home (in the world frame) is at `origin` (`gcs.frames.world_to_geodetic`)."""
    out = []
    for shape in fence.shapes:
        pts = np.column_stack([shape.points, np.zeros(len(shape.points))])
        out.append((shape, frames.world_to_geodetic(pts, home_world, origin)[:, :2]))
    return out


def fence_items(fence: WorldFence, home_world: ArrayLike,
                origin: frames.Geodetic) -> list[FenceItem]:
    """The FENCE list one vehicle is given: `place_shapes` as MISSION_ITEM_INT numbers."""
    items: list[FenceItem] = []
    for shape, lat_lon in place_shapes(fence, home_world, origin):
        e7 = np.rint(lat_lon * 1e7).astype(np.int64)
        if shape.radius is not None:
            command = CIRCLE_INCLUSION if shape.inclusion else CIRCLE_EXCLUSION
            items.append(FenceItem(command, shape.radius, int(e7[0, 0]), int(e7[0, 1])))
            continue
        command = POLYGON_INCLUSION if shape.inclusion else POLYGON_EXCLUSION
        items.extend(FenceItem(command, float(len(e7)), int(x), int(y)) for x, y in e7)
    return items


def item_mismatch(sent: Sequence[FenceItem], got: Sequence[FenceItem]) -> str | None:
    """How a FENCE list read back differs from the one sent (None: the same, x/y within 1
    degE7 and param1 within float32 rounding)."""
    if len(sent) != len(got):
        return f"read back {len(got)} items, sent {len(sent)}"
    for seq, (a, b) in enumerate(zip(sent, got, strict=True)):
        if (a.command != b.command or abs(a.x - b.x) > 1 or abs(a.y - b.y) > 1
                or not abs(a.param1 - b.param1) <= 1e-4 * max(1.0, abs(a.param1))):
            return f"item {seq} read back as {b}, sent {a}"
    return None
