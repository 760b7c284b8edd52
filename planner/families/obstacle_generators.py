"""Scenario generators with obstacles, seeded: the paper's circle around a pillar, a wall
with one window, rows of shelving, a forest of pillars, a wall with no opening, and a crowd
flying from one room to another through one window.

All return scenario dicts (the JSON contract), like `planner.families.generators`; the benchmark
(`bench/planner.py obstacles`) and the examples in `planner/examples/` come from them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from planner.families.generators import _limits, _vehicles, circle_swap, crowd_steps
from planner.types import FloatArray

__all__ = ["forest", "pillar_circle", "sealed_wall", "shelving", "window_rooms", "window_wall"]


def _box(oid: str, low: FloatArray | list[float], high: FloatArray | list[float]
         ) -> dict[str, Any]:
    return {"id": oid, "box": {"min": [round(float(x), 6) for x in low],
                               "max": [round(float(x), 6) for x in high]}}


def _scenario(name: str, dt: float, steps: int, separation: float, clearance: float,
              limits: dict[str, Any], starts: FloatArray, goals: FloatArray,
              obstacles: list[dict[str, Any]]) -> dict[str, Any]:
    """A scenario dict with obstacles and their clearance."""
    return {"name": name, "dt": dt, "steps": steps, "min_separation": separation,
            "obstacle_clearance": clearance, "limits": limits,
            "vehicles": _vehicles(starts, goals), "obstacles": obstacles}


def pillar_circle(vehicles: int = 8, *, seed: int = 0, radius: float = 0.3) -> dict[str, Any]:
    """The paper's circle swap (`planner.families.generators.circle_swap`) around a central pillar
    from floor to ceiling; the seed moves the pillar by up to 0.2 m and its radius by up to
    0.1 m."""
    rng = np.random.default_rng(seed)
    data = circle_swap(vehicles)
    high = data["limits"]["position_max"]
    center = np.array(high[:2]) / 2 + (rng.uniform(-0.2, 0.2, 2) if seed else 0.0)
    r = radius + (float(rng.uniform(-0.1, 0.1)) if seed else 0.0)
    data["name"] = f"pillar-circle{vehicles}-seed{seed}"
    data["obstacles"] = [{"id": "pillar", "cylinder": {
        "center": [round(float(c), 6) for c in center], "radius": round(r, 6),
        "z": [0.0, float(high[2])]}}]
    return data


def _wall_boxes(x: float, thickness: float, width: float, height: float,
                window: tuple[float, float, float, float] | None) -> list[dict[str, Any]]:
    """A wall across the room at x (full width and height), as boxes around a window
    (y0, y1, z0, z1), or one box when there is none."""
    x0, x1 = x - thickness / 2, x + thickness / 2
    if window is None:
        return [_box("wall", [x0, 0.0, 0.0], [x1, width, height])]
    y0, y1, z0, z1 = window
    return [
        _box("wall-left", [x0, 0.0, 0.0], [x1, y0, height]),
        _box("wall-right", [x0, y1, 0.0], [x1, width, height]),
        _box("wall-below", [x0, y0, 0.0], [x1, y1, z0]),
        _box("wall-above", [x0, y0, z1], [x1, y1, height]),
    ]


def window_wall(vehicles: int = 8, *, seed: int = 0, window: tuple[float, float] = (3.0, 2.5),
                separation: float = 0.8, clearance: float = 0.3, dt: float = 0.2,
                steps: int = 120, sealed: bool = False) -> dict[str, Any]:
    """Vehicles, half on each side of a wall across a 12 x 8 x 4 m room, swap sides through
    one window of `window` (width, height) m; the seed moves the window and the vehicles.
    With `sealed`, the wall has no window (no plan can exist)."""
    rng = np.random.default_rng(seed)
    size = np.array([12.0, 8.0, 4.0])
    per_side = vehicles // 2
    wy = float(size[1] / 2 + rng.uniform(-1.0, 1.0))
    wz = float(2.0 + rng.uniform(-0.2, 0.2))
    opening = (wy - window[0] / 2, wy + window[0] / 2, wz - window[1] / 2, wz + window[1] / 2)
    ys = np.linspace(1.0, size[1] - 1.0, per_side) + rng.uniform(-0.2, 0.2, per_side)
    zs = np.where(np.arange(per_side) % 2 == 0, 1.4, 2.6)
    west = np.stack([np.full(per_side, 1.5), ys, zs], axis=1)
    # Each vehicle flies straight across in its lane; the lanes' two directions at
    # different heights.
    east = np.stack([np.full(per_side, size[0] - 1.5), ys, 4.0 - zs], axis=1)
    starts = np.vstack([west, east])
    goals = np.vstack([east, west])
    return _scenario(f"{'sealed' if sealed else 'window'}{vehicles}-seed{seed}", dt, steps,
                     separation, clearance, _limits(np.zeros(3), size, 2.0, 3.0, 6.0),
                     starts, goals, _wall_boxes(size[0] / 2, 0.2, float(size[1]),
                                                float(size[2]), None if sealed else opening))


def sealed_wall(vehicles: int = 2, *, seed: int = 0) -> dict[str, Any]:
    """`window_wall` without its window: every goal is cut off."""
    return window_wall(vehicles, seed=seed, sealed=True)


def shelving(vehicles: int = 16, *, seed: int = 0, rows: int = 4, separation: float = 0.8,
             clearance: float = 0.3, dt: float = 0.2, steps: int = 100) -> dict[str, Any]:
    """Vehicles cross `rows` rows of shelving (2.5-3 m high, 0.8 m deep) in a 20 x 18 x 5 m
    warehouse side by side, from one wall to the other, over the shelves or around their
    ends."""
    rng = np.random.default_rng(seed)
    size = np.array([20.0, 18.0, 5.0])
    obstacles = []
    for r in range(rows):
        y = 4.0 + r * (10.0 / max(rows - 1, 1)) + float(rng.uniform(-0.3, 0.3))
        x0 = 2.5 + float(rng.uniform(0.0, 0.8))
        x1 = size[0] - 2.5 - float(rng.uniform(0.0, 0.8))
        top = 2.5 + float(rng.uniform(0.0, 0.5))
        obstacles.append(_box(f"shelf{r + 1}", [x0, y - 0.4, 0.0], [x1, y + 0.4, top]))
    xs = np.linspace(1.5, size[0] - 1.5, vehicles)
    zs = np.where(np.arange(vehicles) % 2 == 0, 1.5, 2.2)
    starts = np.stack([xs, np.full(vehicles, 1.2), zs], axis=1)
    goals = np.stack([xs, np.full(vehicles, size[1] - 1.2), zs], axis=1)
    return _scenario(f"shelving{vehicles}-seed{seed}", dt, steps, separation, clearance,
                     _limits(np.zeros(3), size, 3.0, 3.0, 8.0), starts, goals, obstacles)


def forest(vehicles: int = 50, pillars: int = 40, *, size: float = 30.0, seed: int = 0,
           separation: float = 0.8, clearance: float = 0.4, dt: float = 0.25,
           steps: int | None = None) -> dict[str, Any]:
    """Vehicles cross a size x size m forest of `pillars` trees (radius 0.2-0.5 m, floor to
    ceiling, 2.5 m apart at least), each in its own lane: half from the west edge to the
    east low (1.0 or 1.8 m), half from the east to the west high (2.8 or 3.6 m), spread
    evenly along the edges, alternating heights."""
    rng = np.random.default_rng(seed)
    height = 4.0
    trees: list[FloatArray] = []
    low, high = np.array([4.0, 1.0]), np.array([size - 4.0, size - 1.0])
    for _ in range(pillars * 2000):
        if len(trees) == pillars:
            break
        c = low + (high - low) * rng.random(2)
        if all(np.linalg.norm(c - t) >= 2.5 for t in trees):
            trees.append(c)
    if len(trees) < pillars:
        raise ValueError(f"cannot place {pillars} pillars 2.5 m apart in {size:g} m")
    obstacles = [{"id": f"tree{n + 1}", "cylinder": {
        "center": [round(float(c[0]), 6), round(float(c[1]), 6)],
        "radius": round(float(rng.uniform(0.2, 0.5)), 6), "z": [0.0, height]}}
        for n, c in enumerate(trees)]
    east_count = vehicles // 2
    west_count = vehicles - east_count
    # Each vehicle keeps its lane: westerners fly east low (1.0 or 1.8 m, alternating
    # along the edge), easterners west high (2.8 or 3.6 m).
    def edge(count: int, x: float, levels: tuple[float, float]) -> FloatArray:
        y = np.linspace(1.0, size - 1.0, count) + rng.uniform(-0.05, 0.05, count)
        z = np.where(np.arange(count) % 2 == 0, levels[0], levels[1])
        return np.stack([np.full(count, x), y, z], axis=1)

    starts = np.vstack([edge(west_count, 1.0, (1.0, 1.8)),
                        edge(east_count, size - 1.0, (2.8, 3.6))])
    goals = starts.copy()
    goals[:, 0] = size - starts[:, 0]
    # Cross at up to 2 m/s with room for detours.
    k = steps if steps is not None else int(np.ceil((1.6 * size / 2.0 + 4.0) / dt))
    return _scenario(f"forest{vehicles}-{pillars}-seed{seed}", dt, k, separation, clearance,
                     _limits(np.zeros(3), np.array([size, size, height]), 3.0, 3.0, 8.0),
                     starts, goals, obstacles)


def window_rooms(vehicles: int = 50, *, seed: int | None = 0, window: float = 3.5,
                 spacing: float = 1.6, height: float = 6.0, separation: float = 0.8,
                 clearance: float = 0.3, dt: float = 0.2, horizon_factor: float = 2.0
                 ) -> dict[str, Any]:
    """Vehicles fly from one room to the next through one square window (`window` m a side,
    mid-height, in a 0.2 m wall at x = 0): they start on a lattice (`spacing` apart, layers
    of vertical grids facing the wall) in the west room and fly to the same lattice in the
    east room, the layer nearest the wall to the farthest one (a layer of vehicles waiting
    or arrived is no wall to the others), each mirrored sideways and in height through the
    window's centre: every path crosses the one window. The horizon is `horizon_factor`
    times the longest move's shortest time (v and a <= 3, jerk <= 5).

    seed: None keeps everything regular; an integer moves the window by up to 0.5 m
    sideways and 0.2 m up or down, and each start by up to a tenth of `spacing`.
    """
    rows = max(1, int((height - 2.0) // spacing) + 1)
    columns = max(1, int(np.ceil(np.sqrt(vehicles / rows))))
    n = np.arange(vehicles)
    per_layer = rows * columns
    layer, column, row = n // per_layer, (n % per_layer) % columns, (n % per_layer) // columns
    width = (columns - 1) * spacing + 4.0
    starts = np.stack([-2.0 - layer * spacing, 2.0 + column * spacing, 1.0 + row * spacing],
                      axis=1).astype(float)
    centre = np.array([0.0, width / 2.0, height / 2.0])
    if seed is not None:
        rng = np.random.default_rng(seed)
        centre[1:] += [rng.uniform(-0.5, 0.5), rng.uniform(-0.2, 0.2)]
        starts += rng.uniform(-0.1, 0.1, starts.shape) * spacing
    goals = 2.0 * centre - starts
    # the layers reversed: the nearest (x = -2) to the farthest, which flies first
    goals[:, 0] = 2.0 + (layer.max() - layer) * spacing - (starts[:, 0] + 2.0 + layer * spacing)
    points = np.concatenate([starts, goals])
    low, high = points.min(axis=0) - 1.5, points.max(axis=0) + 1.5
    low[2], high[2] = 0.0, max(height, float(high[2]))
    half = window / 2.0
    middle = float(centre[1] - low[1])  # _wall_boxes measures y from 0
    opening = (middle - half, middle + half, centre[2] - half, centre[2] + half)
    walls = _wall_boxes(0.0, 0.2, float(high[1] - low[1]), float(high[2]), opening)
    for wall in walls:  # then moved to the workspace's y
        for corner in ("min", "max"):
            wall["box"][corner][1] = round(wall["box"][corner][1] + float(low[1]), 6)
    steps = crowd_steps(starts, goals, dt, horizon_factor)
    name = f"window-rooms{vehicles}-w{window:g}-s{spacing:g}" + (
        "" if seed is None else f"-seed{seed}")
    return _scenario(name, dt, steps, separation, clearance,
                     _limits(low, high, 3.0, 3.0, 5.0), starts, goals, walls)
