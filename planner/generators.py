"""Scenario generators: the paper-style circle swap, seeded random transitions, and the
dmpc2019 benchmark's trial distribution (Luis & Schoellig, RA-L 2019).

All return scenario dicts (the JSON contract), ready for `Scenario.from_dict` or `plan`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DMPC2019_BOX",
    "circle_swap",
    "dmpc2019_points",
    "dmpc2019_scenario",
    "random_transitions",
]

FloatArray = NDArray[np.float64]

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
