"""The crowd families in which every path crosses one point: antipodal swaps on a sphere
shell and on a circle in a thin slab, two facing grids swapping places, and a crowd flying
from room to room through one window."""

from __future__ import annotations

import numpy as np
import pytest

import planner
from planner.families.generators import (
    antipodal_circle,
    antipodal_sphere,
    crowd_steps,
    facing_grids,
)
from planner.families.obstacle_generators import window_rooms
from planner.methods.horizon import shortest_steps


def _closest(points: np.ndarray) -> float:
    d = np.linalg.norm(points[:, None] - points[None], axis=2)
    return float(d[np.triu_indices(len(points), 1)].min())


def _through(scenario: planner.Scenario, point: np.ndarray) -> float:
    """The largest distance from `point` to a vehicle's straight line start -> goal."""
    s, g = scenario.starts, scenario.goals
    move = g - s
    t = np.einsum("nc,nc->n", point - s, move) / np.einsum("nc,nc->n", move, move)
    return float(np.linalg.norm(s + t[:, None] * move - point, axis=1).max())


@pytest.mark.parametrize("seed", [None, 0, 3])
def test_antipodal_sphere_sends_every_vehicle_through_the_centre(seed: int | None) -> None:
    data = antipodal_sphere(100, seed=seed)
    s = planner.Scenario.from_dict(data)
    centre = 0.5 * (s.starts + s.goals)
    assert np.allclose(centre, centre[0], atol=1e-5)
    assert _through(s, centre[0]) < 1e-5
    assert _closest(s.starts) == pytest.approx(2.0, abs=1e-4)
    moves = np.linalg.norm(s.goals - s.starts, axis=1)
    assert moves.min() > 12.5 and moves.max() < 13.5  # ~13 m for 100 at 2 m
    assert (s.steps, s.dt) == (150, 0.2) and s.min_separation == 1.0
    assert np.allclose(s.limits.velocity_max, 3.0)
    radius = np.linalg.norm(s.starts - centre, axis=1)
    assert centre[0, 2] == pytest.approx(radius.max() + 2.0, abs=1e-5)  # 2 m off the ground
    assert (s.starts >= s.limits.position_min).all() and (s.goals <= s.limits.position_max).all()


def test_a_seed_turns_the_sphere_and_other_seeds_differ() -> None:
    a, b = (planner.Scenario.from_dict(antipodal_sphere(50, seed=k)) for k in (1, 2))
    assert not np.allclose(a.starts, b.starts)
    assert _closest(a.starts) == pytest.approx(_closest(b.starts), abs=1e-6)


@pytest.mark.parametrize(("count", "spacing", "thickness"), [(50, 2.0, 1.6), (24, 3.0, 1.2)])
def test_antipodal_circle_crosses_the_centre_in_a_thin_slab(count: int, spacing: float,
                                                            thickness: float) -> None:
    data = antipodal_circle(count, seed=None, spacing=spacing, thickness=thickness)
    s = planner.Scenario.from_dict(data)
    centre = 0.5 * (s.starts[0] + s.goals[0])
    assert _through(s, centre) < 1e-5
    assert _closest(s.starts) == pytest.approx(spacing, abs=1e-4)
    assert s.limits.position_max[2] - s.limits.position_min[2] == pytest.approx(thickness)
    assert np.allclose(s.starts[:, 2], centre[2])  # mid-slab
    # the horizon is 1.5 x the longest move's shortest time at the crowd's boxes
    fewest = shortest_steps(s.goals - s.starts, s.dt, s.limits.velocity_max,
                            s.limits.acceleration_max, s.limits.jerk_max)
    assert s.steps == int(np.ceil(1.5 * fewest))
    assert s.steps == crowd_steps(s.starts, s.goals, s.dt, 1.5)
    # seeds move vehicles along the circle by up to a tenth of the spacing
    seeded = planner.Scenario.from_dict(antipodal_circle(count, seed=4, spacing=spacing))
    shift = np.linalg.norm(seeded.starts - s.starts, axis=1)
    assert shift.max() > 0.0 and shift.max() <= 0.11 * spacing


@pytest.mark.parametrize("pairing", ["centre", "across"])
def test_facing_grids_swap_places(pairing: str) -> None:
    s = planner.Scenario.from_dict(facing_grids(100, seed=None, pairing=pairing, gap=8.0))
    starts, goals = s.starts, s.goals
    assert np.allclose(np.sort(starts, axis=0), np.sort(goals, axis=0))  # places swapped
    assert sorted(np.unique(np.round(starts[:, 1], 6)).tolist()) == [0.0, 8.0]
    assert (starts[:50, 1] == 0.0).all() and (goals[:50, 1] == 8.0).all()
    centre = starts.mean(axis=0)
    if pairing == "centre":
        assert _through(s, centre) < 1e-5
    else:
        assert np.allclose((goals - starts)[:, [0, 2]], 0.0)
    assert _closest(starts) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="pairing"):
        facing_grids(10, pairing="sideways")


def test_window_rooms_fly_the_crowd_through_one_window_nearest_layer_farthest() -> None:
    data = window_rooms(50, seed=2)
    s = planner.Scenario.from_dict(data)
    assert len(s.vehicles) == 50 and len(s.obstacles) == 4
    assert (s.starts[:, 0] < 0).all() and (s.goals[:, 0] > 0).all()  # room to room
    # sideways and in height mirrored through the window's centre
    centre = 0.5 * (s.starts + s.goals)
    assert np.allclose(centre[:, 1:], centre[0, 1:], atol=1e-5)
    # the layer nearest the wall flies to the farthest one, and back to front
    order = np.argsort(-s.starts[:, 0])
    assert np.all(np.diff(s.goals[order, 0]) <= 0.21 * 1.6 + 1e-6)
    assert s.goals[order[0], 0] > s.goals[order[-1], 0] + 1.6
    # the window: a 3.5 m square gap in the wall around that centre, the wall elsewhere
    boxes = {o["id"]: o["box"] for o in data["obstacles"]}
    assert boxes["wall-right"]["min"][1] - boxes["wall-left"]["max"][1] == pytest.approx(3.5)
    assert boxes["wall-above"]["min"][2] - boxes["wall-below"]["max"][2] == pytest.approx(3.5)
    assert boxes["wall-left"]["max"][1] + 1.75 == pytest.approx(centre[0, 1])
    assert boxes["wall-below"]["max"][2] + 1.75 == pytest.approx(centre[0, 2])
    assert boxes["wall-left"]["min"][1] == pytest.approx(s.limits.position_min[1], abs=1e-6)
    assert boxes["wall-right"]["max"][1] == pytest.approx(s.limits.position_max[1], abs=1e-6)
    assert _closest(s.starts) > 0.7 * 1.6
    assert s.steps == crowd_steps(s.starts, s.goals, s.dt, 2.0)


@pytest.mark.parametrize("build", [
    lambda: antipodal_sphere(12), lambda: antipodal_circle(10),
    lambda: facing_grids(12), lambda: window_rooms(8)])
def test_small_crowds_plan_verified(build) -> None:  # type: ignore[no-untyped-def]
    result = planner.plan(build())
    assert result.status == "converged" and result.verification.verified
