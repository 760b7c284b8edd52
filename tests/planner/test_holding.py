"""A vehicle whose goal is its start (it holds in place) is a member of every fleet: its
route has no length, it never departs, and both methods plan the fleet around it."""

from __future__ import annotations

import itertools

import numpy as np

import planner
from planner.families import obstacle_generators as families
from planner.methods.routes import along, blocked_vehicles, holders, route_polylines
from planner.methods.spacetime import depart
from planner.scp.first_qp import straight_moves


def _forest_holding(vehicles: int, trees: int, size: float) -> dict:
    data = families.forest(vehicles, trees, size=size, seed=0)
    data["vehicles"][0]["goal"] = list(data["vehicles"][0]["start"])
    return data


def test_a_route_of_one_point_rests_there_at_any_delay() -> None:
    scenario = planner.Scenario.from_dict(_forest_holding(2, 1, 20.0))
    point = scenario.starts[0]
    for route in (point[None], np.stack([point, point])):
        for delay in (0, 5):
            p, v, a = along(route, scenario, delay)
            assert p.shape == (scenario.steps + 1, 3) and a.shape == (scenario.steps, 3)
            assert np.allclose(p, point) and not v.any() and not a.any()
    # a departure against earlier vehicles passing by: still resting at its point
    beside = point + np.array([0.2, 0.0, 0.0])
    passing = np.repeat((beside / scenario.separation_scale)[None, None],
                        scenario.steps + 1, axis=1)
    p, _, _ = depart(scenario, point[None], passing)
    assert np.allclose(p, point)


def test_prioritized_batches_plan_a_forest_crossing_with_a_vehicle_holding_in_place() -> None:
    data = _forest_holding(20, 20, 20.0)
    result = planner.plan(data, method="prioritized")
    assert result.status == "converged" and result.verification.verified
    assert result.method == "prioritized"
    held = result.vehicles[0].position
    assert np.allclose(held[0], held[-1])
    assert np.allclose(held[-1], data["vehicles"][0]["start"])


def _gap_between_pillars(gap: float) -> dict:
    """Two floor-to-ceiling pillars `gap` m apart (surface to surface) with a vehicle
    holding in place in the middle of the gap, and three vehicles crossing west to east
    whose straight moves lead through it; around the pillars there is room."""
    r = 0.5
    pillars = [{"id": f"p{n}", "cylinder": {"center": [10.0, 10.0 + side * (gap / 2 + r)],
                                             "radius": r, "z": [0.0, 4.0]}}
               for n, side in enumerate((-1, 1))]
    crossing = [{"id": f"w{n}", "start": [1.0, y, 2.0], "goal": [19.0, y, 2.0]}
                for n, y in enumerate((9.0, 10.0, 11.0))]
    return {"name": "gap", "dt": 0.2, "steps": 100, "min_separation": 0.8,
            "obstacle_clearance": 0.4,
            "limits": {"position_min": [0, 0, 0], "position_max": [20, 20, 4],
                       "velocity_max": [3, 3, 3], "acceleration_max": [3, 3, 3],
                       "jerk_max": [8, 8, 8]},
            "vehicles": [{"id": "hold", "start": [10.0, 10.0, 2.0], "goal": [10.0, 10.0, 2.0]},
                         *crossing],
            "obstacles": pillars}


def test_a_vehicle_holding_in_a_gap_is_an_obstacle_to_the_others_routes() -> None:
    # the gap leaves 1.2 m within the clearance: with the holder in it, no way through
    data = _gap_between_pillars(2.0)
    scenario = planner.Scenario.from_dict(data)
    assert holders(scenario).tolist() == [0]
    blocked = blocked_vehicles(scenario, straight_moves(scenario)).tolist()
    assert 0 not in blocked and {1, 2, 3} <= set(blocked)
    found = route_polylines(scenario, np.array([1, 2, 3]))
    for points in found.routes.values():  # each route keeps R from the holder
        samples = np.concatenate([a + np.linspace(0, 1, 50)[:, None] * (b - a)
                                  for a, b in itertools.pairwise(points)])
        assert np.linalg.norm(samples - scenario.starts[0], axis=1).min() >= 0.8


def test_the_whole_fleet_plans_around_a_vehicle_holding_between_obstacles() -> None:
    result = planner.plan(_gap_between_pillars(2.0))
    assert result.status == "converged" and result.verification.verified, result.message
    held = result.vehicles[0].position
    assert np.allclose(held[0], held[-1])
