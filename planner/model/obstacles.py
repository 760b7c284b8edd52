"""Keep-out volumes of a scenario: the JSON model and its validation.

Every obstacle is a convex footprint (a rectangle, a circle or a convex polygon) extruded
vertically over [z0, z1]: a box, a vertical cylinder or a prism. Their geometry, for many
(point, obstacle) pairs at once, is `planner.model.obstacle_set.ObstacleSet`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from planner.errors import ScenarioError
from planner.model.checks import check_id, check_keys, check_list, check_number, check_vector
from planner.types import FloatArray

__all__ = ["MAX_OBSTACLES", "MAX_POLYGON_VERTICES", "BoxShape", "CylinderShape", "Obstacle",
           "PrismShape", "describe", "parse_obstacles"]


#: Most obstacles one scenario may hold (a hard cap on work and memory; the service's
#: `max_obstacles` setting may set a lower one).
MAX_OBSTACLES = 1000
#: Most vertices of one prism's polygon.
MAX_POLYGON_VERTICES = 64
#: Range of `obstacle_clearance` (m) and of a cylinder's radius (m).
CLEARANCE_RANGE = (0.0, 100.0)
RADIUS_RANGE = (1e-3, 1e4)
#: The shapes an obstacle may have, one key each.
_KINDS = ("box", "cylinder", "prism")


@dataclass(frozen=True)
class BoxShape:
    """An axis-aligned box."""

    min: FloatArray
    """Lower corner [x, y, z] (m)."""
    max: FloatArray
    """Upper corner [x, y, z] (m); greater than `min` on every axis."""


@dataclass(frozen=True)
class CylinderShape:
    """A vertical cylinder."""

    center: FloatArray
    """(2,) axis position [x, y] (m)."""
    radius: float
    """Radius (m)."""
    z: FloatArray
    """(2,) bottom and top heights [z0, z1] (m), z0 < z1."""


@dataclass(frozen=True)
class PrismShape:
    """A vertical prism over a convex polygon (buildings)."""

    polygon: FloatArray
    """(V, 2) the footprint's vertices [[x, y], ...], convex, counter-clockwise seen from
    above, at least 3."""
    z: FloatArray
    """(2,) bottom and top heights [z0, z1] (m), z0 < z1."""


@dataclass(frozen=True)
class Obstacle:
    """A keep-out volume: an id and exactly one of `box`, `cylinder`, `prism`."""

    id: str
    """Unique obstacle id, named in errors and in the plan's verification."""
    box: BoxShape | None = None
    """An axis-aligned box."""
    cylinder: CylinderShape | None = None
    """A vertical cylinder."""
    prism: PrismShape | None = None
    """A vertical prism over a convex polygon."""

    def footprint(self) -> tuple[FloatArray, float, float]:
        """(polygon (V, 2) counter-clockwise, or the circle as [[cx, cy, r]]; z0, z1)."""
        if self.box is not None:
            (x0, y0, z0), (x1, y1, z1) = self.box.min, self.box.max
            return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]), float(z0), float(z1)
        if self.cylinder is not None:
            c = self.cylinder
            return (np.array([[c.center[0], c.center[1], c.radius]]), float(c.z[0]),
                    float(c.z[1]))
        assert self.prism is not None
        return self.prism.polygon, float(self.prism.z[0]), float(self.prism.z[1])

    def to_dict(self) -> dict[str, Any]:
        if self.box is not None:
            return {"id": self.id, "box": {"min": self.box.min.tolist(),
                                           "max": self.box.max.tolist()}}
        if self.cylinder is not None:
            c = self.cylinder
            return {"id": self.id, "cylinder": {"center": c.center.tolist(), "radius": c.radius,
                                                "z": c.z.tolist()}}
        assert self.prism is not None
        return {"id": self.id, "prism": {"polygon": self.prism.polygon.tolist(),
                                         "z": self.prism.z.tolist()}}


# --------------------------------------------------------------------------- parsing


def _pair(value: Any, name: str, *, what: str = "[x, y]") -> FloatArray:
    """Two coordinates."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise ScenarioError(name, f"must be a list of 2 numbers {what}")
    return np.array([check_number(c, f"{name}[{i}]", within="coordinate")
                     for i, c in enumerate(value)], dtype=float)


def _heights(value: Any, name: str) -> FloatArray:
    z = _pair(value, name, what="[z0, z1]")
    if z[1] <= z[0]:
        raise ScenarioError(f"{name}[1]", f"must be greater than z0 ({z[0]:g}): the obstacle "
                                          f"has no height")
    return z


def _polygon(value: Any, name: str) -> FloatArray:
    """A convex, counter-clockwise polygon of 3..MAX_POLYGON_VERTICES distinct vertices."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) < 3:
        raise ScenarioError(name, "must be a list of at least 3 vertices [x, y]")
    if len(value) > MAX_POLYGON_VERTICES:
        raise ScenarioError(name, f"at most {MAX_POLYGON_VERTICES} vertices, got {len(value)}")
    poly = np.array([_pair(v, f"{name}[{i}]") for i, v in enumerate(value)])
    edges = np.roll(poly, -1, axis=0) - poly
    size = float(np.max(np.ptp(poly, axis=0)))
    length = np.linalg.norm(edges, axis=1)
    if size <= 0 or np.any(length <= 1e-9 * max(size, 1.0)):
        short = int(np.argmin(length))
        raise ScenarioError(f"{name}[{(short + 1) % len(poly)}]",
                            "repeats the previous vertex (zero-length edge)")
    turn = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(
        edges, -1, axis=0)[:, 0]
    area = 0.5 * float(np.sum(poly[:, 0] * np.roll(poly[:, 1], -1)
                              - np.roll(poly[:, 0], -1) * poly[:, 1]))
    if area < 0:
        raise ScenarioError(name, "must be counter-clockwise seen from above (its vertices run "
                                  "clockwise)")
    flat = turn <= 1e-9 * size * size
    if area <= 1e-12 * size * size or flat.any():
        at = int(np.argmax(flat)) if flat.any() else 0
        raise ScenarioError(f"{name}[{(at + 1) % len(poly)}]",
                            "makes the polygon non-convex or degenerate (every vertex must turn "
                            "left, no three in a line)")
    # Strictly left turns at every vertex and positive area can still wind twice around.
    angles = np.arctan2(edges[:, 1], edges[:, 0])
    winding = np.sum(np.mod(np.diff(np.append(angles, angles[0])), 2 * np.pi))
    if winding > 2 * np.pi + 1e-6:
        raise ScenarioError(name, "must be a simple convex polygon (it winds around more than "
                                  "once)")
    return poly


def _shape(raw: Any, where: str) -> tuple[str, Any]:
    check_keys(raw, {"id", *_KINDS}, where, ("id",))
    kinds = [k for k in _KINDS if k in raw]
    if len(kinds) != 1:
        raise ScenarioError(where, "must have exactly one of box, cylinder, prism"
                            + (f", got {', '.join(kinds)}" if kinds else ""))
    kind = kinds[0]
    body = raw[kind]
    at = f"{where}.{kind}"
    if kind == "box":
        check_keys(body, {"min", "max"}, at, ("min", "max"))
        lo, hi = check_vector(body["min"], f"{at}.min"), check_vector(body["max"], f"{at}.max")
        for axis in range(3):
            if hi[axis] <= lo[axis]:
                raise ScenarioError(f"{at}.max[{axis}]", f"must be greater than min[{axis}] "
                                                         f"({lo[axis]:g}): the box has no size")
        return kind, BoxShape(lo, hi)
    if kind == "cylinder":
        check_keys(body, {"center", "radius", "z"}, at, ("center", "radius", "z"))
        center = _pair(body["center"], f"{at}.center")
        radius = check_number(body["radius"], f"{at}.radius", positive=True)
        if not RADIUS_RANGE[0] <= radius <= RADIUS_RANGE[1]:
            raise ScenarioError(f"{at}.radius", f"must be between {RADIUS_RANGE[0]:g} and "
                                                f"{RADIUS_RANGE[1]:g} m, got {radius:g}")
        return kind, CylinderShape(center, radius, _heights(body["z"], f"{at}.z"))
    check_keys(body, {"polygon", "z"}, at, ("polygon", "z"))
    return kind, PrismShape(_polygon(body["polygon"], f"{at}.polygon"),
                            _heights(body["z"], f"{at}.z"))


def parse_obstacles(data: Mapping[str, Any], min_separation: float
                    ) -> tuple[tuple[Obstacle, ...], float]:
    """The scenario's `obstacles` and `obstacle_clearance` (default min_separation / 2);
    raises `ScenarioError` naming the field."""
    clearance = check_number(data.get("obstacle_clearance", 0.5 * min_separation),
                             "obstacle_clearance", nonneg=True)
    if not CLEARANCE_RANGE[0] <= clearance <= CLEARANCE_RANGE[1]:
        raise ScenarioError("obstacle_clearance", f"must be between {CLEARANCE_RANGE[0]:g} and "
                                                  f"{CLEARANCE_RANGE[1]:g} m, got {clearance:g}")
    raw = check_list(data.get("obstacles", []), "obstacles", "obstacles", MAX_OBSTACLES)
    out: list[Obstacle] = []
    seen: dict[str, int] = {}
    for index, item in enumerate(raw):
        where = f"obstacles[{index}]"
        kind, shape = _shape(item, where)
        oid = check_id(item["id"], f"{where}.id")
        if oid in seen:
            raise ScenarioError(f"{where}.id",
                                f"duplicate id {oid!r} (also obstacles[{seen[oid]}])")
        seen[oid] = index
        out.append(Obstacle(oid, **{kind: shape}))
    return tuple(out), clearance


def describe(ids: Sequence[str], limit: int = 8) -> str:
    """Obstacle ids for a message, at most `limit` of them."""
    shown = ", ".join(repr(i) for i in ids[:limit])
    return shown + (f" and {len(ids) - limit} more" if len(ids) > limit else "")

