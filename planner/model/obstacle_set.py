"""The obstacles' geometry: `ObstacleSet` holds a scenario's obstacles
(`planner.model.obstacles`) as padded numpy arrays so that signed distances and supporting
planes are computed for many (point, obstacle) pairs at once; the planner's rows
(`planner.scp.obstacle_rows`), its route search (`planner.methods.routes`), the verifier
(`planner.verification.clearance`) and the scenario's check that no start or goal lies in an
obstacle (`check_clear`) all use it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.errors import ScenarioError
from planner.model.obstacles import Obstacle
from planner.types import FloatArray, IntArray

__all__ = ["ObstacleSet", "check_clear"]


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
