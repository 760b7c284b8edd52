"""Keep-out volumes of a scenario: the JSON model, its validation, and their geometry.

Every obstacle is a convex footprint (a rectangle, a circle or a convex polygon) extruded
vertically over [z0, z1]: a box, a vertical cylinder or a prism. `ObstacleSet` holds them as
padded numpy arrays so that signed distances and supporting planes are computed for many
(point, obstacle) pairs at once; the planner's rows (`planner.scp.obstacle_rows`), its route
search (`planner.methods.routes`) and the verifier (`planner.verification.clearance`) all use it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from planner.errors import ScenarioError
from planner.model.checks import check_id, check_keys, check_list, check_number, check_vector
from planner.types import FloatArray, IntArray

__all__ = ["MAX_OBSTACLES", "MAX_POLYGON_VERTICES", "BoxShape", "CylinderShape", "Obstacle",
           "ObstacleSet", "PrismShape", "check_clear", "describe", "parse_obstacles"]


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


def check_clear(obstacles: tuple[Obstacle, ...], clearance: float, points: FloatArray,
                label: str) -> None:
    """Refuses the first of `points` ((N, 3), vehicles' starts or goals: `label`) that lies
    within `clearance` of an obstacle, naming the vehicle and the obstacle."""
    if not obstacles:
        return
    geometry = ObstacleSet.build(obstacles)
    n, m = len(points), len(obstacles)
    vehicle = np.repeat(np.arange(n), m)
    obstacle = np.tile(np.arange(m), n)
    distance = geometry.signed_distance(points[vehicle], obstacle)
    bad = np.flatnonzero(distance < clearance)
    if bad.size == 0:
        return
    first = int(bad[0])
    v, o, d = int(vehicle[first]), int(obstacle[first]), float(distance[first])
    detail = "" if d <= 0 else f": {d:.3g} m from its surface"
    raise ScenarioError(f"vehicles[{v}].{label}",
                        f"{points[v].tolist()} lies inside obstacle {obstacles[o].id!r} "
                        f"(clearance {clearance:g} m){detail}")


# --------------------------------------------------------------------------- geometry


def _unit2(x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit vectors along the last axis (2-D) and their norms (0-safe)."""
    norm = np.sqrt(np.einsum("...c,...c->...", x, x))
    return x / np.where(norm > 1e-300, norm, 1.0)[..., None], norm


@dataclass(frozen=True)
class ObstacleSet:
    """Every obstacle as arrays: footprints (convex polygons padded to one vertex count, or
    circles), heights, and bounding boxes; vectorised distance queries."""

    ids: tuple[str, ...]
    circle: IntArray
    """(M,) bool as int: 1 where the footprint is a circle."""
    center: FloatArray
    """(M, 2) circle centres (0 for polygons)."""
    radius: FloatArray
    """(M,) circle radii (0 for polygons)."""
    vertex: FloatArray
    """(M, V, 2) polygon vertices, the last repeated as padding (circles: zeros)."""
    normal: FloatArray
    """(M, V, 2) outward unit edge normals (0 for padding edges and circles)."""
    offset: FloatArray
    """(M, V) n'x <= offset inside each edge (+inf for padding, so it never decides)."""
    z: FloatArray
    """(M, 2) bottom and top."""
    lo: FloatArray
    """(M, 3) bounding box lower corners."""
    hi: FloatArray
    """(M, 3) bounding box upper corners."""

    def __len__(self) -> int:
        return len(self.ids)

    @staticmethod
    def build(obstacles: Sequence[Obstacle]) -> ObstacleSet:
        m = len(obstacles)
        shapes = [o.footprint() for o in obstacles]
        width = max([len(s[0]) for s in shapes if s[0].shape[1] == 2] + [1])
        circle = np.zeros(m, dtype=np.intp)
        center, radius = np.zeros((m, 2)), np.zeros(m)
        vertex, normal = np.zeros((m, width, 2)), np.zeros((m, width, 2))
        offset = np.full((m, width), np.inf)
        z, lo, hi = np.zeros((m, 2)), np.zeros((m, 3)), np.zeros((m, 3))
        for index, (foot, z0, z1) in enumerate(shapes):
            z[index] = (z0, z1)
            if foot.shape[1] == 3:
                circle[index] = 1
                center[index], radius[index] = foot[0, :2], foot[0, 2]
                lo[index] = (*(foot[0, :2] - foot[0, 2]), z0)
                hi[index] = (*(foot[0, :2] + foot[0, 2]), z1)
                continue
            count = len(foot)
            vertex[index, :count] = foot
            vertex[index, count:] = foot[-1]
            edge = np.roll(foot, -1, axis=0) - foot
            n, _ = _unit2(np.stack([edge[:, 1], -edge[:, 0]], axis=1))
            normal[index, :count] = n
            offset[index, :count] = np.einsum("vc,vc->v", n, foot)
            lo[index] = (*foot.min(axis=0), z0)
            hi[index] = (*foot.max(axis=0), z1)
        return ObstacleSet(tuple(o.id for o in obstacles), circle, center, radius, vertex,
                           normal, offset, z, lo, hi)

    def horizontal(self, q: FloatArray, o: IntArray, fallback: FloatArray | None = None
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Signed horizontal distance of points q (Q, 2) to footprints o (Q,), the nearest
        footprint boundary point and the outward unit normal there. fallback (Q, 2): the
        direction to use where a point lies on a cylinder's axis (default +x)."""
        if fallback is None:
            fallback = np.broadcast_to(np.array([1.0, 0.0]), (len(q), 2))
        dh = np.empty(len(q))
        point, normal = np.empty((len(q), 2)), np.empty((len(q), 2))
        circ = self.circle[o].astype(bool)
        if circ.any():
            c, r = self.center[o[circ]], self.radius[o[circ]]
            n, norm = _unit2(q[circ] - c)
            n = np.where((norm > 1e-12)[:, None], n, fallback[circ])
            dh[circ], point[circ], normal[circ] = norm - r, c + r[:, None] * n, n
        poly = ~circ
        if poly.any():
            qp, op = q[poly], o[poly]
            a = self.vertex[op]  # (Q, V, 2)
            edge = np.roll(a, -1, axis=1) - a
            length2 = np.einsum("qvc,qvc->qv", edge, edge)
            rel = qp[:, None, :] - a
            t = np.clip(np.einsum("qvc,qvc->qv", rel, edge) / np.maximum(length2, 1e-300),
                        0.0, 1.0)
            near = a + t[..., None] * edge
            dist = np.sqrt(np.einsum("qvc,qvc->qv", qp[:, None, :] - near,
                                     qp[:, None, :] - near))
            side = np.einsum("qvc,qc->qv", self.normal[op], qp) - self.offset[op]
            inside = side.max(axis=1) <= 0.0
            rows = np.arange(len(qp))
            best = np.argmin(dist, axis=1)
            out_point = near[rows, best]
            out_normal, out_norm = _unit2(qp - out_point)
            deepest = np.argmax(side, axis=1)  # the nearest edge line from inside
            in_normal = self.normal[op][rows, deepest]
            in_depth = side[rows, deepest]
            dh[poly] = np.where(inside, in_depth, out_norm)
            point[poly] = np.where(inside[:, None], qp - in_depth[:, None] * in_normal,
                                   out_point)
            normal[poly] = np.where(inside[:, None], in_normal, out_normal)
        return dh, point, normal

    def support(self, q: FloatArray, o: IntArray, fallback: FloatArray | None = None
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For points q (Q, 3) and obstacles o (Q,): signed distance (negative inside), the
        obstacle's point nearest q (its nearest boundary point from inside) and the outward
        unit normal there. The plane through that point with that normal supports the convex
        obstacle: every point x of it has n'x <= n'point. fallback (Q, 2): the horizontal
        direction to use where a point lies on a cylinder's axis."""
        q = np.asarray(q, dtype=float)
        o = np.asarray(o, dtype=np.intp)
        if fallback is None:
            fallback = np.broadcast_to(np.array([1.0, 0.0]), (len(q), 2))
        dh, hpoint, hnormal = self.horizontal(q[:, :2], o, fallback)
        z0, z1 = self.z[o, 0], self.z[o, 1]
        zq = q[:, 2]
        below, above = z0 - zq, zq - z1
        dz = np.maximum(below, above)
        zface = np.where(below > above, z0, z1)
        up = np.where(below > above, -1.0, 1.0)
        both = (dh > 0) & (dz > 0)
        horizontal = np.where(both | (dh > 0), True, np.where(dz > 0, False, dh >= dz))
        distance = np.where(both, np.hypot(np.maximum(dh, 0), np.maximum(dz, 0)),
                            np.maximum(dh, dz))
        point = np.empty_like(q)
        point[:, :2] = np.where(horizontal[:, None], hpoint, q[:, :2])
        point[:, 2] = np.where(horizontal & ~both, zq, zface)
        normal = np.zeros_like(q)
        normal[:, :2] = np.where(horizontal[:, None], hnormal, 0.0)
        normal[:, 2] = np.where(horizontal, 0.0, up)
        if both.any():
            diff = q[both] - point[both]
            normal[both] = diff / np.linalg.norm(diff, axis=1)[:, None]
        return distance, point, normal

    def signed_distance(self, q: FloatArray, o: IntArray) -> FloatArray:
        """Signed distance of points q (Q, 3) to obstacles o (Q,) (negative inside)."""
        return self.support(q, o)[0]

    def near(self, lo: FloatArray, hi: FloatArray, reach: float
             ) -> tuple[IntArray, IntArray]:
        """(box, obstacle) index pairs of query boxes [lo, hi] ((B, 3) each) within `reach`
        of an obstacle's bounding box along every axis (a superset of the boxes within
        `reach` of the obstacle): the broad phase, a k-d tree over the boxes' centres."""
        if len(lo) == 0 or len(self) == 0:
            z = np.zeros(0, dtype=np.intp)
            return z, z
        from scipy.spatial import cKDTree

        centre = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        tree = cKDTree(centre)
        box_reach = float(np.linalg.norm(half, axis=1).max())
        o_centre = 0.5 * (self.lo + self.hi)
        o_half = np.linalg.norm(0.5 * (self.hi - self.lo), axis=1)
        hits = tree.query_ball_point(o_centre, o_half + box_reach + reach)
        counts = np.array([len(h) for h in hits], dtype=np.intp)
        if counts.sum() == 0:
            z = np.zeros(0, dtype=np.intp)
            return z, z
        boxes = np.concatenate([np.asarray(h, dtype=np.intp) for h in hits if h])
        obstacle = np.repeat(np.arange(len(self)), counts)
        gap = np.maximum(self.lo[obstacle] - hi[boxes], lo[boxes] - self.hi[obstacle])
        keep = (gap <= reach).all(axis=1)
        return boxes[keep], obstacle[keep]


def describe(ids: Sequence[str], limit: int = 8) -> str:
    """Obstacle ids for a message, at most `limit` of them."""
    shown = ", ".join(repr(i) for i in ids[:limit])
    return shown + (f" and {len(ids) - limit} more" if len(ids) > limit else "")

