"""A vehicle whose goal is its start (it holds in place) is a member of every fleet: its
route has no length, it never departs, and both methods plan the fleet around it."""

from __future__ import annotations

import numpy as np

import planner
from planner import obstacle_generators as families
from planner.routes import along
from planner.scp import ScpOptions
from planner.spacetime import depart


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
    result = planner.plan(data, options=ScpOptions(decompose="prioritized"))
    assert result.status == "converged" and result.verification.verified
    assert "prioritized batches" in result.message
    held = result.vehicles[0].position
    assert np.allclose(held[0], held[-1])
    assert np.allclose(held[-1], data["vehicles"][0]["start"])
