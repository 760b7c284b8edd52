"""Space-time seeding of prioritized batches among obstacles: routes searched once for the
fleet, departures that wait until the earlier vehicles' motion leaves the route free, and
the verdict on an unreachable goal before any batch is planned."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

import planner
import planner.methods.prioritized as prioritized
import planner.methods.route_grid as route_grid
import planner.methods.routes as routes
import planner.methods.spacetime as spacetime
from planner.families import obstacle_generators as families
from planner.methods.routes import along, blocked_vehicles
from planner.methods.spacetime import depart, fleet_routes, route_segments
from planner.result import IterationRecord
from planner.scp.first_qp import straight_moves
from planner.scp.loop import ScpOptions, ScpOutcome
from planner.scp.obstacle_rows import ObstacleRows
from planner.scp.solvers import make_solver
from planner.types import IntArray


def test_fleet_routes_give_every_vehicle_a_polyline_from_its_start_to_its_goal() -> None:
    scenario = planner.Scenario.from_dict(families.forest(12, 10, size=20.0, seed=0))
    found = fleet_routes(scenario)
    assert found.unreachable is None
    assert sorted(found.routes) == list(range(12))
    blocked = set(blocked_vehicles(scenario, straight_moves(scenario)).tolist())
    assert blocked  # the forest is in the way of some lanes
    for i, points in found.routes.items():
        assert np.allclose(points[0], scenario.starts[i])
        assert np.allclose(points[-1], scenario.goals[i])
        assert (len(points) > 2) == (i in blocked)  # a clear lane stays straight
    # the routes themselves keep clear of the obstacles (up to the grid's half cell)
    moves = [along(found.routes[i], scenario) for i in range(12)]
    lin = (np.stack([m[0] for m in moves]), np.stack([m[1] for m in moves]),
           np.stack([m[2] for m in moves]))
    half = dataclasses.replace(scenario, obstacle_clearance=0.5 * scenario.clearance)
    assert blocked_vehicles(half, lin).size == 0


def test_a_departure_waits_until_the_earlier_vehicle_has_passed_at_every_step() -> None:
    scenario = planner.Scenario.from_dict(families.forest(2, 1, size=20.0, seed=0))
    route = np.stack([scenario.starts[0], scenario.goals[0]])
    scale = scenario.separation_scale
    # an earlier vehicle crosses the route's middle at the very time the route gets there
    mine = along(route, scenario)[0]
    k = scenario.steps // 2
    across = np.array([0.0, 6.0, 0.0])
    other = mine[k] + np.linspace(-1.0, 1.0, scenario.steps + 1)[:, None] * across
    need = spacetime.ROUTE_GAP * scenario.min_separation
    gap0 = np.linalg.norm((mine - other) / scale, axis=1).min()
    assert gap0 < need  # departing at once would meet it
    p, v, a = depart(scenario, route, (other / scale)[None])
    assert np.linalg.norm((p - other) / scale, axis=1).min() >= need
    assert np.allclose(p[0], route[0]) and np.allclose(p[-1], route[-1])
    assert np.allclose(v[0], 0.0) and np.allclose(v[-1], 0.0)
    assert a.shape == (scenario.steps, 3)
    # it waits at its start, then moves along the route (here a straight line)
    waited = int(np.argmax(np.linalg.norm(p - p[0], axis=1) > 1e-9))
    assert waited > 0
    off_line = np.cross(p - route[0], route[1] - route[0])
    assert np.allclose(off_line, 0.0, atol=1e-9)
    # with nothing placed before it, it departs at once
    assert np.allclose(depart(scenario, route, np.zeros((0, 1, 3)))[0], mine)


def test_batches_among_obstacles_route_once_for_the_fleet_and_plan_verified(
        monkeypatch: pytest.MonkeyPatch) -> None:
    data = families.forest(12, 10, size=20.0, seed=0)
    searched: list[int] = []
    original = routes.route_polylines

    def counting(scenario: planner.Scenario, blocked: IntArray) -> routes.Polylines:
        searched.append(len(blocked))
        return original(scenario, blocked)

    monkeypatch.setattr(routes, "route_polylines", counting)  # inside the SCP's seeding
    monkeypatch.setattr(spacetime, "route_polylines", counting)
    result = planner.plan(data, method="prioritized")
    assert result.ok, result.problems()
    assert "prioritized batches" in result.message
    assert len(searched) == 1  # once for the fleet, not per batch nor inside the SCP
    check = result.verification
    assert check is not None and check.clear and check.obstacle_distance_min is not None
    assert check.obstacle_distance_min >= result.scenario.clearance - check.separation_tolerance


def test_an_unreachable_goal_is_still_infeasible_at_once_in_batches() -> None:
    data = families.sealed_wall(4)  # more than one batch: the batches look first
    began = time.perf_counter()
    result = planner.plan(data, method="prioritized")
    assert time.perf_counter() - began < 10.0  # loose: no SCP iteration ran
    assert result.status == "infeasible" and result.infeasible_groups == ("obstacles",)
    assert "vehicles[0] ('uav1') cannot reach its goal" in result.message
    assert "not in prioritized batches: a goal cannot be reached around the obstacles" \
        in result.message
    scenario = planner.Scenario.from_dict(data)
    found = fleet_routes(scenario)
    assert found.routes == {} and found.vehicle == 0
    assert found.unreachable is not None and "'wall' cut it off" in found.unreachable


def test_batches_seed_more_obstacle_rows_and_the_option_is_checked() -> None:
    scenario = planner.Scenario.from_dict(families.forest(12, 10, size=20.0, seed=0))
    lin = straight_moves(scenario)
    narrow = ObstacleRows(scenario).seed(lin)
    wide = ObstacleRows(scenario, spacetime.BATCH_OBSTACLE_SEED).seed(lin)
    assert set(narrow.tolist()) < set(wide.tolist())
    with pytest.raises(ValueError, match="obstacle_seed"):
        ScpOptions(obstacle_seed=0.0)


def test_a_batch_fixes_the_earlier_vehicles_near_its_route_not_only_its_straight_move(
        ) -> None:
    scenario = planner.Scenario.from_dict(families.forest(2, 1, size=20.0, seed=0))
    start, goal = scenario.starts[0], scenario.goals[0]
    bend = 0.5 * (start + goal) + np.array([0.0, 6.0, 0.0])  # 6 m off the straight move
    route = {0: np.stack([start, bend, goal])}
    a, b = route_segments(scenario, np.array([0]), route)
    assert np.allclose(a, [start, bend]) and np.allclose(b, [bend, goal])
    # an earlier vehicle resting by the bend: out of reach of the straight move only
    resting = np.repeat((bend + np.array([0.0, 0.5, 0.0]))[None, None, :],
                        scenario.steps + 1, axis=1)
    reach = prioritized.REACH * scenario.min_separation
    members = np.array([0])
    assert prioritized.near_fixed(scenario, members, resting, reach).size == 0
    assert prioritized.near_fixed(scenario, members, resting, reach, route).tolist() == [0]


def test_full_height_obstacles_are_routed_in_the_plane_at_the_lanes_own_heights() -> None:
    scenario = planner.Scenario.from_dict(families.forest(12, 10, size=20.0, seed=0))
    grid = route_grid.build_grid(scenario)
    assert grid.planar and grid.shape[2] == 1  # trees floor to ceiling: one layer
    assert not route_grid.build_grid(
        planner.Scenario.from_dict(families.window_wall(8, seed=1))).planar
    found = fleet_routes(scenario)
    for i, points in found.routes.items():  # each lane keeps its height (start = goal z)
        assert np.allclose(points[:, 2], scenario.starts[i, 2])


def test_a_full_height_wall_still_cuts_the_goals_off_at_once() -> None:
    data = families.forest(2, 1, size=20.0, seed=0)
    data["obstacles"].append({"id": "wall", "box": {"min": [9.8, 0.0, 0.0],
                                                    "max": [10.2, 20.0, 4.0]}})
    scenario = planner.Scenario.from_dict(data)
    assert route_grid.build_grid(scenario).planar
    result = planner.plan(data, method="prioritized")
    assert result.status == "infeasible" and result.infeasible_groups == ("obstacles",)
    assert "cannot reach its goal" in result.message and "'wall'" in result.message


def test_a_batch_stopped_at_its_iteration_cap_continues_from_where_it_stopped(
        monkeypatch: pytest.MonkeyPatch) -> None:
    data = families.forest(6, 6, size=20.0, seed=0)
    data["max_iterations"] = 1  # stops while its first iteration still moved the cost
    scenario = planner.Scenario.from_dict(data).assigned()
    runs: list[tuple[np.ndarray, ScpOutcome, list[IterationRecord]]] = []
    real = spacetime.run_scp

    def recording(sub, solver, options, progress, start, routed):
        outcome = real(sub, solver, options, progress, start, routed=routed)
        runs.append((start[0], outcome, list(outcome.iterations)))
        return outcome

    monkeypatch.setattr(spacetime, "run_scp", recording)
    found = fleet_routes(scenario)
    routed = tuple(np.stack(x) for x in zip(*(along(found.routes[i], scenario)
                                               for i in range(6)), strict=True))
    outcome = spacetime.continued_scp(scenario, make_solver(None), None, None,
                                      (routed[0], routed[1], routed[2]))
    assert len(runs) == 2 and runs[0][1].status == "max_iterations"
    assert np.array_equal(runs[1][0], runs[0][1].positions)  # from where it stopped
    assert outcome.iterations == runs[0][2] + runs[1][2]  # both runs' iterations
