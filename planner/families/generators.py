"""Scenario generators: the paper-style circle swap, seeded random transitions, the
dmpc2019 benchmark's trial distribution (Luis & Schoellig, RA-L 2019), and the drone-show
families (grid -> sphere show transitions, dense random transitions).

Long: a catalogue of scenario families, each a short independent function.

All return scenario dicts (the JSON contract), ready for `Scenario.from_dict` or `plan`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from planner.types import FloatArray

__all__ = [
    "DMPC2019_BOX",
    "SHOW_SHAPES",
    "antipodal_circle",
    "antipodal_sphere",
    "circle_swap",
    "crowd_steps",
    "dmpc2019_points",
    "dmpc2019_scenario",
    "facing_grids",
    "formation",
    "free_steps",
    "grid_to_sphere",
    "random_dense",
    "random_transitions",
    "show_formations",
    "show_sequence",
    "sideways",
    "sphere_shell",
    "vertical_grid",
]


#: The dmpc2019 benchmark's box: 1.5874 m a side, 4.00 m^3.
DMPC2019_BOX = (np.array([-0.7937, -0.7937, 0.2]), np.array([0.7937, 0.7937, 1.7874]))
DMPC2019_SEPARATION = 0.35
DMPC2019_SCALE = np.array([1.0, 1.0, 2.0])
#: Candidate draws per point before the authors' generator restarts the whole set.
DMPC2019_MAX_TRIES = 200_000


def _limits(low: FloatArray, high: FloatArray, velocity: float | None, acceleration: float,
            jerk: float | None) -> dict[str, Any]:
    limits: dict[str, Any] = {
        "position_min": [float(x) for x in low],
        "position_max": [float(x) for x in high],
        "acceleration_max": [acceleration] * 3,
    }
    if velocity is not None:
        limits["velocity_max"] = [velocity] * 3
    if jerk is not None:
        limits["jerk_max"] = [jerk] * 3
    return limits


def _vehicles(starts: FloatArray, goals: FloatArray) -> list[dict[str, Any]]:
    return [
        {"id": f"uav{n + 1}", "start": [round(float(c), 6) for c in s],
         "goal": [round(float(c), 6) for c in g]}
        for n, (s, g) in enumerate(zip(starts, goals, strict=True))
    ]


def circle_swap(vehicles: int, *, radius: float | None = None, height: float = 1.5,
                height_step: float = 0.8, rotation: float = 0.2, separation: float = 1.0,
                dt: float = 0.2, steps: int = 150) -> dict[str, Any]:
    """Vehicles evenly on a horizontal circle, each flying to the opposite side (rotated by
    `rotation` rad so no pair meets exactly head-on), at alternating heights."""
    if radius is None:
        # Neighbours on the circle at least 1.2 R apart.
        radius = max(2.0, 1.2 * separation / (2.0 * np.sin(np.pi / max(vehicles, 2))))
    angle = 2.0 * np.pi * np.arange(vehicles) / vehicles
    z = height + np.where(np.arange(vehicles) % 2 == 0, -height_step / 2, height_step / 2)
    center = radius + 0.5
    starts = np.stack([center + radius * np.cos(angle), center + radius * np.sin(angle), z], 1)
    goal_angle = angle + np.pi + rotation
    goals = np.stack(
        [center + radius * np.cos(goal_angle), center + radius * np.sin(goal_angle), z], 1
    )
    high = np.array([2 * center, 2 * center, height + height_step + 1.0])
    return {
        "name": f"circle{vehicles}",
        "dt": dt,
        "steps": steps,
        "min_separation": separation,
        "limits": _limits(np.zeros(3), high, 2.0, 3.0, 5.0),
        "vehicles": _vehicles(starts, goals),
    }


def _spread_points(rng: np.random.Generator, count: int, low: FloatArray, high: FloatArray,
                   separation: float, scale: FloatArray, margin: float) -> FloatArray:
    points: list[FloatArray] = []
    for _ in range(count * 10_000):
        if len(points) == count:
            break
        candidate = low + margin + (high - low - 2 * margin) * rng.random(3)
        if all(np.linalg.norm((candidate - p) / scale) > separation for p in points):
            points.append(candidate)
    if len(points) < count:
        raise ValueError(f"cannot place {count} points {separation} m apart in the box")
    return np.array(points)


def random_transitions(vehicles: int, *, size: tuple[float, float, float] = (10.0, 10.0, 4.0),
                       seed: int = 0, separation: float = 1.0, spacing: float = 1.2,
                       dt: float = 0.2, steps: int = 150) -> dict[str, Any]:
    """Seeded random starts and goals in a box, each set `spacing` * R apart."""
    rng = np.random.default_rng(seed)
    low, high = np.zeros(3), np.array(size, dtype=float)
    starts = _spread_points(rng, vehicles, low, high, spacing * separation, np.ones(3), 0.3)
    goals = _spread_points(rng, vehicles, low, high, spacing * separation, np.ones(3), 0.3)
    return {
        "name": f"random{vehicles}-seed{seed}",
        "dt": dt,
        "steps": steps,
        "min_separation": separation,
        "limits": _limits(low, high, 2.0, 3.0, 5.0),
        "vehicles": _vehicles(starts, goals),
    }


def dmpc2019_points(random_sample: Any, count: int) -> FloatArray:
    """One point set of the authors' `randomTest`: uniform candidates in the box, each kept
    only if strictly farther than 0.35 m (metric diag(1, 1, 1/2)) from all kept ones.

    random_sample: a callable returning `n` uniform doubles (e.g. numpy's legacy
    `RandomState(seed).random_sample`, which is MATLAB's default Mersenne Twister stream).
    Each candidate draws x, y, z in that order.
    """
    low, high = DMPC2019_BOX
    while True:
        points: list[FloatArray] = []
        for _ in range(count):
            for _ in range(DMPC2019_MAX_TRIES):
                candidate = low + (high - low) * np.asarray(random_sample(3), dtype=float)
                if all(np.linalg.norm((candidate - p) / DMPC2019_SCALE) > DMPC2019_SEPARATION
                       for p in points):
                    points.append(candidate)
                    break
            else:
                break  # the authors restart the whole set
        if len(points) == count:
            return np.array(points)


def dmpc2019_scenario(vehicles: int, *, seed: int = 0, trial: int = 0,
                      horizon: float = 10.0, dt: float = 0.2) -> dict[str, Any]:
    """A dmpc2019-distributed trial: random starts then goals (independent sets, random
    assignment), 0.35 m ellipsoid [1, 1, 2], |a| <= 1 m/s^2 per axis, no v or jerk bound."""
    state = np.random.RandomState(seed * 1000 + trial)
    starts = dmpc2019_points(state.random_sample, vehicles)
    goals = dmpc2019_points(state.random_sample, vehicles)
    low, high = DMPC2019_BOX
    return {
        "name": f"dmpc2019-n{vehicles}-seed{seed}-trial{trial}",
        "dt": dt,
        "steps": round(horizon / dt),
        "min_separation": DMPC2019_SEPARATION,
        "separation_scale": DMPC2019_SCALE.tolist(),
        "limits": _limits(low, high, None, 1.0, None),
        "vehicles": _vehicles(starts, goals),
    }


# --------------------------------------------------------------------------- drone-show families

#: Horizon, limits and separation of the show families: 30 s, v and a <= 3,
#: jerk <= 5, R = 1 m.
SHOW_DT, SHOW_STEPS, SHOW_SEPARATION = 0.2, 150, 1.0
#: Volume per vehicle of random128 (128 vehicles in 40 x 40 x 8 m).
RANDOM128_VOLUME = 40.0 * 40.0 * 8.0 / 128


def vertical_grid(count: int, spacing: float = 2.0, base: float = 2.0) -> FloatArray:
    """`count` points of a near-square vertical grid in the x-z plane (y = 0), centred on
    x = 0, lowest row at z = `base`, row by row from the bottom."""
    columns = int(np.ceil(np.sqrt(count)))
    n = np.arange(count)
    x = (n % columns - (columns - 1) / 2.0) * spacing
    z = base + (n // columns) * spacing
    return np.stack([x, np.zeros(count), z], axis=1)


def sphere_shell(count: int, spacing: float = 2.1) -> FloatArray:
    """`count` points on a sphere centred at the origin (Fibonacci lattice), the radius chosen
    so that the closest two points are exactly `spacing` apart."""
    n = np.arange(count) + 0.5
    polar = np.arccos(1.0 - 2.0 * n / count)
    azimuth = np.pi * (1.0 + 5.0**0.5) * n
    unit = np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar),
                     np.cos(polar)], axis=1)
    if count < 2:
        return unit * spacing
    return unit * (spacing / _closest(unit))


def grid_to_sphere(vehicles: int, *, seed: int | None = 0, grid_spacing: float = 2.0,
                   sphere_spacing: float = 2.1, separation: float = SHOW_SEPARATION,
                   dt: float = SHOW_DT, steps: int | None = SHOW_STEPS) -> dict[str, Any]:
    """A show transition: a vertical grid (`grid_spacing` apart) converging onto a sphere shell
    (closest goals `sphere_spacing` apart) centred on the grid's centre, 30 s, v and a <= 3,
    jerk <= 5, R = 1 m.

    seed: the goals are a seeded random permutation of the shell's points (a crowded fixed
    assignment, every path crossing the middle); None keeps the lattice order, both sorted
    bottom to top. With `"assignment": "free"` the order does not matter.
    steps: None sizes the horizon to the free assignment's moves: the fewest steps at which
    every assigned move's straight profile respects the boxes (`planner.methods.horizon`), which
    solves the assignment once here (30 s is too short from about 4,000 vehicles on).
    """
    grid = vertical_grid(vehicles, grid_spacing)
    shell = sphere_shell(vehicles, sphere_spacing)
    centre = np.array([0.0, 0.0, 0.5 * (grid[:, 2].min() + grid[:, 2].max())])
    radius = float(np.linalg.norm(shell[0])) if vehicles else 0.0
    centre[2] = max(centre[2], radius + 1.0)  # keep the shell above the ground
    goals = shell + centre
    if seed is not None:
        goals = goals[np.random.default_rng(seed).permutation(vehicles)]
    name = f"grid-sphere{vehicles}" + ("" if seed is None else f"-seed{seed}")
    if steps is None:
        steps = free_steps(grid, goals, dt)
    return _show_change(name, grid, goals, separation, dt, steps)


def free_steps(starts: FloatArray, goals: FloatArray, dt: float = SHOW_DT,
               velocity: float = 3.0, acceleration: float = 3.0, jerk: float = 5.0) -> int:
    """The fewest steps of `dt` in which the free assignment's moves from `starts` to `goals`
    fit the show families' boxes (v, a <= 3, jerk <= 5 by default) as straight
    rest-to-rest profiles: the horizon a show change of these formations needs."""
    from planner.methods.assignment import solve_assignment
    from planner.methods.horizon import shortest_steps

    order = solve_assignment(starts, goals).order
    return shortest_steps(goals[order] - starts, dt, np.full(3, velocity),
                          np.full(3, acceleration), np.full(3, jerk))


def _show_change(name: str, starts: FloatArray, goals: FloatArray, separation: float,
                 dt: float, steps: int) -> dict[str, Any]:
    """A show transition's scenario: the workspace 2 m around every start and goal (from the
    ground up), v and a <= 3, jerk <= 5."""
    points = np.concatenate([starts, goals])
    low = points.min(axis=0) - 2.0
    high = points.max(axis=0) + 2.0
    low[2] = 0.0
    return {
        "name": name,
        "dt": dt,
        "steps": steps,
        "min_separation": separation,
        "limits": _limits(low, high, 3.0, 3.0, 5.0),
        "vehicles": _vehicles(starts, goals),
    }


def _rotation(rng: np.random.Generator) -> FloatArray:
    """A uniformly random 3-D rotation matrix (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))[None, :]
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return np.asarray(q)


def sideways(vehicles: int, *, seed: int | None = None, spacing: float = 2.0,
             sphere_spacing: float | None = None, offset: float = 4.0,
             separation: float = SHOW_SEPARATION, dt: float = SHOW_DT,
             steps: int = SHOW_STEPS) -> dict[str, Any]:
    """A show transition flown sideways: a vertical grid (`spacing` apart, in the x-z plane)
    onto a sphere shell beside it (closest goals `sphere_spacing` apart, default 1.05 x
    `spacing`), the shell's nearest point `offset` m beyond the grid's last column, its
    lowest point 2 m up. Goals in lattice order (grid bottom to top, shell top to bottom):
    a fixed assignment under which the whole fleet moves as one crowd, side by side and
    partly through each other. 30 s, v and a <= 3, jerk <= 5, R = 1 m.

    seed: None keeps the shell's Fibonacci lattice as built; an integer turns the shell by
    a seeded random rotation about its centre (same points relative to each other, same
    order, other pairings in space).
    """
    grid = vertical_grid(vehicles, spacing)
    shell = sphere_shell(vehicles, 1.05 * spacing if sphere_spacing is None else sphere_spacing)
    if seed is not None:
        shell = shell @ _rotation(np.random.default_rng(seed)).T
    radius = float(np.linalg.norm(shell[0])) if vehicles else 0.0
    centre = np.array([float(grid[:, 0].max()) + radius + offset, 0.0, radius + 2.0])
    goals = shell + centre
    name = f"sideways{vehicles}-s{spacing:g}-o{offset:g}" + (
        "" if seed is None else f"-seed{seed}")
    return _show_change(name, grid, goals, separation, dt, steps)


def _spread_vectorised(rng: np.random.Generator, count: int, low: FloatArray, high: FloatArray,
                       spacing: float, near: FloatArray | None = None,
                       reach: float = np.inf) -> FloatArray:
    """Points `spacing` apart, drawn uniformly in the box (or, with `near`, within `reach` of
    near[n] for point n), by rejection; raises ValueError when the box is too full."""
    points = np.empty((count, 3))
    for n in range(count):
        for _ in range(10_000):
            if near is None:
                candidate = low + (high - low) * rng.random(3)
            else:
                direction = rng.normal(size=3)
                direction /= max(float(np.linalg.norm(direction)), 1e-12)
                candidate = near[n] + direction * reach * rng.random() ** (1.0 / 3.0)
                if np.any(candidate < low) or np.any(candidate > high):
                    continue
            if n == 0 or np.min(np.linalg.norm(points[:n] - candidate, axis=1)) > spacing:
                points[n] = candidate
                break
        else:
            raise ValueError(f"cannot place {count} points {spacing} m apart in the box")
    return points


def random_dense(vehicles: int, *, seed: int = 0, max_move: float = 40.0, height: float = 8.0,
                 volume_per_vehicle: float = RANDOM128_VOLUME, separation: float = 1.0,
                 spacing: float = 1.2, dt: float = SHOW_DT, steps: int = SHOW_STEPS
                 ) -> dict[str, Any]:
    """Random transitions at random128's density (100 m^3 per vehicle, 8 m high, square
    footprint), each goal within `max_move` of its start, 30 s, random128's limits
    (v <= 2, a <= 3, jerk <= 5); starts and goals each `spacing` * R apart."""
    side = float(np.sqrt(vehicles * volume_per_vehicle / height))
    low, high = np.full(3, 0.3), np.array([side, side, height]) - 0.3
    rng = np.random.default_rng(seed)
    starts = _spread_vectorised(rng, vehicles, low, high, spacing * separation)
    goals = _spread_vectorised(rng, vehicles, low, high, spacing * separation, starts,
                               max_move)
    return {
        "name": f"dense{vehicles}-seed{seed}",
        "dt": dt,
        "steps": steps,
        "min_separation": separation,
        "limits": _limits(np.zeros(3), np.array([side, side, height]), 2.0, 3.0, 5.0),
        "vehicles": _vehicles(starts, goals),
    }


def show_sequence(vehicles: int, *, seed: int = 0, hold: float = 2.0,
                  duration: float = SHOW_DT * SHOW_STEPS) -> dict[str, Any]:
    """A formation sequence (the `planner.methods.sequence` JSON): vertical grid -> sphere shell ->
    the grid again, free assignment, `hold` s on every formation, `duration` s per leg."""
    scenario = grid_to_sphere(vehicles, seed=seed)
    grid = [v["start"] for v in scenario["vehicles"]]
    sphere = [v["goal"] for v in scenario["vehicles"]]
    return {
        "name": f"grid-sphere-grid{vehicles}-seed{seed}",
        "dt": scenario["dt"],
        "min_separation": scenario["min_separation"],
        "limits": scenario["limits"],
        "assignment": "free",
        "vehicles": [v["id"] for v in scenario["vehicles"]],
        "formations": [
            {"name": "grid", "positions": grid, "hold": hold},
            {"name": "sphere", "positions": sphere, "duration": duration, "hold": hold},
            {"name": "grid", "positions": grid, "duration": duration, "hold": hold},
        ],
    }


# --------------------------------------------------------------------------- long shows

#: The formation shapes of `formation`, in the default order of `show_formations`: a vertical
#: grid, a sphere shell, a horizontal torus, a filled cubic lattice, a horizontal grid, and a
#: vertical cylinder. Surfaces, a volume, planes of either orientation.
SHOW_SHAPES = ("grid", "sphere", "torus", "cube", "carpet", "cylinder")


def _closest(points: FloatArray) -> float:
    """The smallest distance between two of `points` (k-d tree, no N x N array)."""
    from scipy.spatial import cKDTree

    distance, _ = cKDTree(points).query(points, k=2)
    return float(distance[:, 1].min())


def _near_square(count: int) -> tuple[FloatArray, FloatArray]:
    """Column and row coordinates (unit spacing, centred) of a near-square grid, row by row."""
    columns = int(np.ceil(np.sqrt(count)))
    n = np.arange(count, dtype=np.float64)
    rows = int(np.ceil(count / columns))
    return n % columns - (columns - 1) / 2.0, n // columns - (rows - 1) / 2.0


def _torus(count: int) -> FloatArray:
    """Rings of points around a horizontal torus (major radius 3 x minor), alternate rings
    turned by half a step: as many rings as fit twice the points per ring."""
    per_ring = max(3, int(np.ceil(np.sqrt(count / 2.0))))
    rings = int(np.ceil(count / per_ring))
    n = np.arange(count)
    ring, slot = n // per_ring, n % per_ring
    u = 2.0 * np.pi * ring / rings
    w = 2.0 * np.pi * (slot + 0.5 * (ring % 2)) / per_ring
    major = 3.0 + np.cos(w)
    return np.stack([major * np.cos(u), major * np.sin(u), np.sin(w)], axis=1)


def _cylinder(count: int) -> FloatArray:
    """Horizontal rings stacked into a vertical cylinder as tall as it is wide, alternate
    rings turned by half a step."""
    per_ring = max(3, int(np.ceil(np.sqrt(np.pi * count))))
    n = np.arange(count)
    ring, slot = n // per_ring, n % per_ring
    w = 2.0 * np.pi * (slot + 0.5 * (ring % 2)) / per_ring
    radius = 1.0 / (2.0 * np.sin(np.pi / per_ring))  # neighbours on a ring 1 apart
    return np.stack([radius * np.cos(w), radius * np.sin(w), ring - ring.max() / 2.0], axis=1)


def formation(shape: str, count: int, spacing: float = 2.0) -> FloatArray:
    """`count` points of a show formation centred on the origin, the closest two exactly
    `spacing` apart: one of `SHOW_SHAPES`. Raises ValueError for another shape."""
    if shape == "grid":
        x, z = _near_square(count)
        unit = np.stack([x, np.zeros(count), z], axis=1)
    elif shape == "carpet":
        x, y = _near_square(count)
        unit = np.stack([x, y, np.zeros(count)], axis=1)
    elif shape == "sphere":
        return sphere_shell(count, spacing)
    elif shape == "torus":
        unit = _torus(count)
    elif shape == "cube":
        side = int(np.ceil(count ** (1.0 / 3.0) - 1e-9))
        n = np.arange(count)
        unit = np.stack([n % side, (n // side) % side, n // (side * side)], axis=1).astype(float)
        unit -= 0.5 * (unit.min(axis=0) + unit.max(axis=0))
    elif shape == "cylinder":
        unit = _cylinder(count)
    else:
        raise ValueError(f"unknown formation shape {shape!r}: one of {', '.join(SHOW_SHAPES)}")
    if count < 2:
        return unit * spacing
    return unit * (spacing / _closest(unit))


def _leg_seconds(moves: FloatArray, limits: dict[str, Any], dt: float) -> float:
    """The shortest whole number of seconds (at least 2) in which synchronised straight
    moves keep 95 % of the velocity, acceleration and jerk bounds (`planner.methods.horizon`)."""
    from planner.methods.horizon import shortest_steps

    v, a, j = (np.asarray(limits[key], dtype=float) * 0.95
               for key in ("velocity_max", "acceleration_max", "jerk_max"))
    return float(max(2, math.ceil(shortest_steps(moves, dt, v, a, j) * dt - 1e-9)))


def show_formations(vehicles: int, shapes: tuple[str, ...] | list[str] = SHOW_SHAPES[:5], *,
                    seed: int | None = 0, spacing: float = 2.0, hold: float = 2.0,
                    separation: float = SHOW_SEPARATION, dt: float = SHOW_DT
                    ) -> dict[str, Any]:
    """A long show (the `planner.methods.sequence` JSON): one formation per entry of `shapes` (see
    `formation`, neighbours `spacing` apart, >= sqrt(2) R keeps CAPT's straight moves
    separated), all centred on one point with their lowest at least 2 m up, free assignment,
    `hold` s on every formation. v and a <= 3, jerk <= 5, R = 1 m; the workspace 2 m around
    every formation. Each leg lasts the whole seconds its assigned moves need (sized here
    from the optimal assignment, which the planner finds again).

    seed: None keeps every shape as built; an integer turns each formation by a seeded
    random angle about the vertical (other pairings, same shapes).
    """
    from planner.methods.assignment import assign_goals

    if len(shapes) < 2:
        raise ValueError("a show needs at least two formations")
    if spacing < separation:
        raise ValueError(f"spacing {spacing:g} m is under the separation R = {separation:g} m")
    rng = np.random.default_rng(seed)
    points = []
    for shape in shapes:
        shape_points = formation(shape, vehicles, spacing)
        if seed is not None:
            angle = rng.uniform(0.0, 2.0 * np.pi)
            c, s = np.cos(angle), np.sin(angle)
            shape_points = shape_points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
        points.append(shape_points)
    centre_height = 2.0 + max(-float(p[:, 2].min()) for p in points)
    points = [p + np.array([0.0, 0.0, centre_height]) for p in points]
    everything = np.concatenate(points)
    low, high = everything.min(axis=0) - 2.0, everything.max(axis=0) + 2.0
    low[2] = 0.0
    limits = _limits(low, high, 3.0, 3.0, 5.0)
    rounded = [np.round(p, 6) for p in points]
    formations: list[dict[str, Any]] = [
        {"name": shapes[0], "positions": rounded[0].tolist(), "hold": hold}]
    where = rounded[0]
    for shape, goals in zip(shapes[1:], rounded[1:], strict=True):
        order = assign_goals(where, goals)
        seconds = _leg_seconds(goals[order] - where, limits, dt)
        formations.append({"name": shape, "positions": goals.tolist(), "duration": seconds,
                           "hold": hold})
        where = goals[order]
    return {
        "name": f"show{vehicles}-{'-'.join(shapes)}" + ("" if seed is None else f"-seed{seed}"),
        "dt": dt,
        "min_separation": separation,
        "limits": limits,
        "assignment": "free",
        "vehicles": [f"uav{n + 1}" for n in range(vehicles)],
        "formations": formations,
    }


# --------------------------------------------------------------------------- crowds through a point

#: Speed (m/s) and acceleration (m/s^2) of the crowd families, as the show families.
CROWD_SPEED, CROWD_ACCELERATION, CROWD_JERK = 3.0, 3.0, 5.0


def _crowd(name: str, starts: FloatArray, goals: FloatArray, separation: float, dt: float,
           steps: int, low: FloatArray, high: FloatArray) -> dict[str, Any]:
    """A crowd family's scenario: v and a <= CROWD_SPEED/ACCELERATION, jerk <= CROWD_JERK."""
    return {
        "name": name,
        "dt": dt,
        "steps": steps,
        "min_separation": separation,
        "limits": _limits(low, high, CROWD_SPEED, CROWD_ACCELERATION, CROWD_JERK),
        "vehicles": _vehicles(starts, goals),
    }


def crowd_steps(starts: FloatArray, goals: FloatArray, dt: float, factor: float) -> int:
    """`factor` times the fewest steps in which the longest of the moves fits the crowd
    families' boxes as a straight rest-to-rest profile (`planner.methods.horizon`), rounded up."""
    from planner.methods.horizon import shortest_steps

    limit = np.full(3, CROWD_SPEED)
    fewest = shortest_steps(goals - starts, dt, limit, np.full(3, CROWD_ACCELERATION),
                            np.full(3, CROWD_JERK))
    return math.ceil(factor * fewest)


def antipodal_sphere(vehicles: int, *, seed: int | None = 0, spacing: float = 2.0,
                     separation: float = SHOW_SEPARATION, dt: float = SHOW_DT,
                     steps: int = SHOW_STEPS) -> dict[str, Any]:
    """Vehicles on a sphere shell (closest neighbours `spacing` apart, `sphere_shell`), each
    flying to its antipode: every path crosses the centre (13 m moves for 100 at 2 m).
    30 s, v and a <= 3, jerk <= 5, R = 1 m; the lowest point 2 m up.

    seed: None keeps the Fibonacci lattice as built; an integer turns it by a seeded random
    rotation about its centre (same crowd, other directions to the ground and the boxes).
    """
    shell = sphere_shell(vehicles, spacing)
    if seed is not None:
        shell = shell @ _rotation(np.random.default_rng(seed)).T
    radius = float(np.linalg.norm(shell, axis=1).max()) if vehicles else 0.0
    centre = np.array([0.0, 0.0, radius + 2.0])
    starts, goals = centre + shell, centre - shell
    low, high = centre - radius - 2.0, centre + radius + 2.0
    low[2] = 0.0
    name = f"antipodal-sphere{vehicles}-s{spacing:g}" + ("" if seed is None else f"-seed{seed}")
    return _crowd(name, starts, goals, separation, dt, steps, low, high)


def antipodal_circle(vehicles: int, *, seed: int | None = 0, spacing: float = 2.0,
                     thickness: float = 1.6, separation: float = SHOW_SEPARATION,
                     dt: float = SHOW_DT, horizon_factor: float = 1.5) -> dict[str, Any]:
    """Vehicles evenly on a horizontal circle (neighbours `spacing` apart) at mid-height of a
    slab `thickness` m thick (the workspace's height), each flying to its antipode: every
    path crosses the centre, and the slab leaves little room to pass above one another.
    The horizon is `horizon_factor` times the longest move's shortest time (v and a <= 3,
    jerk <= 5); R = 1 m.

    seed: None keeps the vehicles evenly spaced; an integer moves each by up to a tenth of
    `spacing` along the circle (no two pairs meet exactly alike).
    """
    count = max(vehicles, 2)
    radius = spacing / (2.0 * np.sin(np.pi / count))
    angle = 2.0 * np.pi * np.arange(vehicles) / count
    if seed is not None:
        jitter = np.random.default_rng(seed).uniform(-0.1, 0.1, vehicles)
        angle = angle + jitter * spacing / radius
    height = 2.0
    centre = np.array([radius + 2.0, radius + 2.0, height])
    ring = radius * np.stack([np.cos(angle), np.sin(angle), np.zeros(vehicles)], axis=1)
    starts, goals = centre + ring, centre - ring
    low = np.array([0.0, 0.0, height - thickness / 2.0])
    high = np.array([2.0 * centre[0], 2.0 * centre[1], height + thickness / 2.0])
    steps = crowd_steps(starts, goals, dt, horizon_factor)
    name = (f"antipodal-circle{vehicles}-s{spacing:g}-t{thickness:g}"
            + ("" if seed is None else f"-seed{seed}"))
    return _crowd(name, starts, goals, separation, dt, steps, low, high)


def facing_grids(vehicles: int, *, seed: int | None = 0, spacing: float = 2.0,
                 gap: float = 10.0, pairing: str = "centre",
                 separation: float = SHOW_SEPARATION, dt: float = SHOW_DT,
                 steps: int = SHOW_STEPS) -> dict[str, Any]:
    """Two vertical grids (`spacing` apart, in x-z planes) facing each other `gap` m apart,
    half the vehicles in each, swapping places. 30 s, v and a <= 3, jerk <= 5, R = 1 m; the
    lowest row 2 m up.

    pairing: "centre" sends each vehicle to the other grid's point mirrored through the
    centre between the grids (every path crosses that centre); "across" to the point facing
    it (pairs meet head-on halfway). Raises ValueError for another pairing.
    seed: None keeps the grids regular; an integer moves each point by up to a tenth of
    `spacing` in its grid's plane (no two pairs meet exactly alike).
    """
    if pairing not in ("centre", "across"):
        raise ValueError(f"unknown pairing {pairing!r}: 'centre' or 'across'")
    half = vehicles - vehicles // 2
    grid = vertical_grid(half, spacing)
    if seed is not None:
        shift = np.random.default_rng(seed).uniform(-0.1, 0.1, (half, 3)) * spacing
        shift[:, 1] = 0.0
        grid = grid + shift
    top = float(grid[:, 2].max()) if half else 0.0
    centre = np.array([0.0, gap / 2.0, 0.5 * (2.0 + top)])
    # the other grid: mirrored through the centre, or facing straight across
    far = 2.0 * centre - grid if pairing == "centre" else grid + np.array([0.0, gap, 0.0])
    starts = np.concatenate([grid, far])[:vehicles]
    goals = np.concatenate([far, grid])[:vehicles]
    low = np.minimum(starts.min(axis=0), goals.min(axis=0)) - 2.0
    high = np.maximum(starts.max(axis=0), goals.max(axis=0)) + 2.0
    low[2] = 0.0
    name = f"facing-grids{vehicles}-{pairing}-s{spacing:g}-g{gap:g}" + (
        "" if seed is None else f"-seed{seed}")
    return _crowd(name, starts, goals, separation, dt, steps, low, high)
