"""Obstacles: the scenario contract, the planes behind the rows, route seeding, the early
verdict on unreachable goals, and the independent continuous-time clearance check."""

from __future__ import annotations

import json
import time
from typing import Any

import numpy as np
import pytest

import planner
from planner.families import obstacle_generators as families
from planner.methods.routes import seed_routes
from planner.model.obstacle_set import ObstacleSet
from planner.model.obstacles import MAX_OBSTACLES, parse_obstacles
from planner.scp.first_qp import straight_moves
from planner.scp.obstacle_rows import ObstacleRows, Triples, control_points
from planner.verification.verify import verify
from tests.planner.conftest import load_example

PILLAR = {"id": "pillar", "cylinder": {"center": [2.5, 2.5], "radius": 0.3, "z": [0.0, 3.0]}}


def _with(obstacles: list[dict[str, Any]], **changes: Any) -> dict[str, Any]:
    data = load_example("paper-circle4")
    data["obstacles"] = obstacles
    data.update(changes)
    return data


def _refusal(data: dict[str, Any]) -> planner.ScenarioError:
    with pytest.raises(planner.ScenarioError) as caught:
        planner.Scenario.from_dict(data)
    return caught.value


# --------------------------------------------------------------------------- the contract


def test_a_goal_within_the_clearance_is_named_with_the_obstacle() -> None:
    data = _with([PILLAR])
    data["vehicles"][3]["goal"] = [2.5, 2.55, 1.5]
    error = _refusal(data)
    assert str(error) == ("vehicles[3].goal: [2.5, 2.55, 1.5] lies inside obstacle 'pillar' "
                          "(clearance 0.5 m)")
    data["vehicles"][3]["goal"] = [2.5, 3.1, 1.5]  # outside the solid, inside the clearance
    error = _refusal(data)
    assert error.field == "vehicles[3].goal"
    assert "'pillar' (clearance 0.5 m): 0.3 m from its surface" in error.reason
    data["obstacle_clearance"] = 0.2  # the clearance decides
    planner.Scenario.from_dict(data)


def test_a_start_within_the_clearance_is_refused() -> None:
    box = {"id": "crate", "box": {"min": [4.0, 2.0, 0.0], "max": [4.4, 3.0, 1.0]}}
    error = _refusal(_with([box]))  # uav1 starts at (4.5, 2.5, 1.1)
    assert error.field == "vehicles[0].start" and "'crate'" in error.reason


@pytest.mark.parametrize(
    ("obstacle", "field", "reason"),
    [
        ({"id": "b", "box": {"min": [1, 1, 0], "max": [1, 2, 1]}}, "obstacles[0].box.max[0]",
         "the box has no size"),
        ({"id": "b", "box": {"min": [1, 1, 2], "max": [2, 2, 1]}}, "obstacles[0].box.max[2]",
         "must be greater than min[2]"),
        ({"id": "b", "box": {"min": [1, 1, 0], "max": [2, float("nan"), 1]}},
         "obstacles[0].box.max[1]", "finite"),
        ({"id": "c", "cylinder": {"center": [1, 1], "radius": 0, "z": [0, 1]}},
         "obstacles[0].cylinder.radius", "positive"),
        ({"id": "c", "cylinder": {"center": [1, 1], "radius": 0.2, "z": [1, 1]}},
         "obstacles[0].cylinder.z[1]", "no height"),
        ({"id": "c", "cylinder": {"center": [1, 1, 1], "radius": 0.2, "z": [0, 1]}},
         "obstacles[0].cylinder.center", "list of 2 numbers"),
        ({"id": "p", "prism": {"polygon": [[0, 0], [0, 1], [1, 0]], "z": [0, 1]}},
         "obstacles[0].prism.polygon", "counter-clockwise"),
        ({"id": "p", "prism": {"polygon": [[0, 0], [2, 0], [1, 0.2], [1, 2]], "z": [0, 1]}},
         "obstacles[0].prism.polygon[2]", "non-convex"),
        ({"id": "p", "prism": {"polygon": [[0, 0], [1, 0], [2, 0]], "z": [0, 1]}},
         "obstacles[0].prism.polygon[1]", "non-convex or degenerate"),
        ({"id": "p", "prism": {"polygon": [[0, 0], [1, 0], [1, 0], [0, 1]], "z": [0, 1]}},
         "obstacles[0].prism.polygon[2]", "zero-length edge"),
        ({"id": "p", "prism": {"polygon": [[0, 0], [1, 0]], "z": [0, 1]}},
         "obstacles[0].prism.polygon", "at least 3"),
        ({"id": "x", "box": {"min": [1, 1, 0], "max": [2, 2, 1]},
          "cylinder": {"center": [1, 1], "radius": 0.2, "z": [0, 1]}},
         "obstacles[0]", "exactly one of box, cylinder, prism"),
        ({"id": "x"}, "obstacles[0]", "exactly one of"),
        ({"id": "", "box": {"min": [1, 1, 0], "max": [2, 2, 1]}}, "obstacles[0].id",
         "non-empty"),
        ({"id": "x", "sphere": {}}, "obstacles[0].sphere", "unknown key"),
    ],
)
def test_malformed_obstacles_are_named(obstacle: dict[str, Any], field: str, reason: str
                                       ) -> None:
    error = _refusal(_with([obstacle]))
    assert error.field == field and reason in error.reason, str(error)


def test_duplicate_ids_too_many_obstacles_and_a_bad_clearance_are_refused() -> None:
    box = {"box": {"min": [0.1, 0.1, 0.0], "max": [0.2, 0.2, 0.1]}}
    error = _refusal(_with([{"id": "a", **box}, {"id": "a", **box}]))
    assert error.field == "obstacles[1].id" and "duplicate id 'a' (also obstacles[0])" in str(
        error)
    error = _refusal(_with([{"id": f"o{n}", **box} for n in range(MAX_OBSTACLES + 1)]))
    assert error.field == "obstacles" and f"at most {MAX_OBSTACLES}" in error.reason
    assert _refusal(_with([], obstacle_clearance=-0.1)).field == "obstacle_clearance"
    assert _refusal(_with([], obstacle_clearance=float("inf"))).field == "obstacle_clearance"


def test_the_scenario_echo_fills_the_clearance_and_round_trips() -> None:
    scenario = planner.Scenario.from_dict(_with([PILLAR]))
    echo = scenario.to_dict()
    assert echo["obstacle_clearance"] == 0.5  # min_separation / 2
    assert echo["obstacles"] == [PILLAR | {"cylinder": {"center": [2.5, 2.5], "radius": 0.3,
                                                         "z": [0.0, 3.0]}}]
    assert planner.Scenario.from_dict(echo).to_dict() == echo
    # Without obstacles the echo is as it always was.
    assert "obstacles" not in planner.Scenario.from_dict(load_example("paper-circle4")).to_dict()


# --------------------------------------------------------------------------- geometry and rows


def _random_obstacles(rng: np.random.Generator) -> list[dict[str, Any]]:
    angle = np.sort(rng.uniform(0, 2 * np.pi, 5))
    polygon = np.stack([np.cos(angle), np.sin(angle)], axis=1) * rng.uniform(0.5, 1.5)
    return [
        {"id": "box", "box": {"min": [-1.0, -0.5, 0.0], "max": [1.0, 0.5, 2.0]}},
        {"id": "cyl", "cylinder": {"center": [0.0, 0.0], "radius": float(rng.uniform(0.2, 1)),
                                   "z": [0.5, 2.5]}},
        {"id": "prism", "prism": {"polygon": polygon.tolist(), "z": [0.0, 1.5]}},
    ]


@pytest.mark.parametrize("seed", range(6))
def test_a_row_keeps_the_whole_step_clear(seed: int) -> None:
    """Any step whose three control points satisfy its row stays at least the clearance
    from the obstacle at every instant, wherever the linearisation point was (outside,
    inside, on the axis)."""
    rng = np.random.default_rng(seed)
    obstacles, clearance = parse_obstacles({"obstacles": _random_obstacles(rng),
                                            "obstacle_clearance": 0.3}, 1.0)
    geometry = ObstacleSet.build(obstacles)
    data = load_example("paper-circle2") | {
        "obstacles": [o.to_dict() for o in obstacles], "obstacle_clearance": clearance,
        "limits": {"position_min": [-5, -5, -2], "position_max": [5, 5, 5]}, "steps": 6}
    data["vehicles"] = [{"id": "a", "start": [-4, -4, 1], "goal": [4, 4, 1]}]
    rows = ObstacleRows(planner.Scenario.from_dict(data))
    count = 400
    lin = rng.uniform(-2.5, 2.5, (count, 7, 3))
    t = Triples(np.arange(count), rng.integers(0, 3, count), rng.integers(1, 5, count))
    normal, rhs = rows.planes(lin, t)
    # Steps whose control points satisfy the row: projected onto its half-space.
    p = rng.uniform(-3, 3, (count, 3, 3))
    shift = np.maximum(0.0, rhs[:, None] - np.einsum("tpc,tc->tp", p, normal))
    p = p + (shift + rng.uniform(0, 0.5, (count, 3)))[..., None] * normal[:, None, :]
    s = np.linspace(0.0, 1.0, 41)
    bernstein = np.stack([(1 - s) ** 2, 2 * s * (1 - s), s * s], axis=1)  # (S, 3)
    curve = np.einsum("sp,tpc->tsc", bernstein, p)
    distance = geometry.signed_distance(curve.reshape(-1, 3), np.repeat(t.obstacle, len(s)))
    assert distance.min() >= clearance - 1e-9


def test_control_points_bound_the_exact_motion() -> None:
    rng = np.random.default_rng(3)
    p, v = rng.normal(size=(2, 5, 3)), rng.normal(size=(2, 5, 3))
    cp = control_points(p, v, 0.2)
    assert np.allclose(cp[:, :, 1], p[:, :-1] + 0.1 * v[:, :-1])
    assert np.allclose(cp[:, :, 2], p[:, 1:])


# --------------------------------------------------------------------------- planning


def test_route_seeding_goes_through_the_window_and_scp_follows() -> None:
    data = families.window_wall(8, seed=1)
    scenario = planner.Scenario.from_dict(data)
    seeded = seed_routes(scenario, straight_moves(scenario))
    # The outer lanes meet the wall: they get routes; the middle ones fly through as they are.
    assert seeded.unreachable is None and seeded.routed == (0, 3, 4, 7)
    below = next(o for o in data["obstacles"] if o["id"] == "wall-below")["box"]
    y0, y1 = below["min"][1], below["max"][1]
    z0 = below["max"][2]
    z1 = next(o for o in data["obstacles"] if o["id"] == "wall-above")["box"]["min"][2]
    p = seeded.guess[0]
    for path in p:  # where each path crosses the wall's plane x = 6, it is in the window
        k = int(np.argmin(np.abs(path[:, 0] - 6.0)))
        assert y0 < path[k, 1] < y1 and z0 < path[k, 2] < z1
    result = planner.plan(scenario)
    assert result.ok, result.problems()
    assert result.verification is not None
    assert result.verification.obstacle_distance_min >= scenario.clearance - 1e-4


def test_an_unreachable_goal_is_named_at_once() -> None:
    data = families.sealed_wall(2)
    began = time.perf_counter()
    result = planner.plan(data)
    assert time.perf_counter() - began < 10.0  # loose: no SCP iteration ran
    assert result.status == "infeasible" and result.infeasible_groups == ("obstacles",)
    assert "vehicles[0] ('uav1') cannot reach its goal" in result.message
    assert "'wall' cut it off" in result.message
    assert len(result.iterations) == 1  # the separation-free first QP only
    assert result.verification is None and not result.ok


def test_a_gap_narrower_than_the_clearance_allows_is_unreachable_too() -> None:
    data = families.window_wall(2, window=(0.25, 0.25), clearance=0.3)
    result = planner.plan(data)
    assert result.status == "infeasible"
    assert {"'wall-left'", "'wall-right'"} <= set(result.message.replace(",", " ").split())


@pytest.mark.parametrize("name", ["pillar-circle8", "window8", "forest20"])
def test_each_obstacle_example_plans_converged_and_verified(name: str) -> None:
    result = planner.plan(load_example(name))
    assert result.ok, result.problems()
    check = result.verification
    assert check is not None and check.clear
    clearance = result.scenario.clearance
    assert check.obstacle_distance_min >= clearance - check.separation_tolerance
    assert check.closest_obstacle is not None
    assert check.closest_obstacle["vehicle"] in result.scenario.ids
    # The plan JSON carries the figures and reads back.
    document = json.loads(json.dumps(result.to_dict()))
    assert document["verification"]["closest_obstacle"] == check.closest_obstacle
    again = planner.Plan.from_dict(document)
    assert again.verification == check


def test_a_plan_without_obstacles_has_no_obstacle_fields() -> None:
    result = planner.plan(load_example("paper-circle4"))
    document = result.to_dict()
    assert "obstacles" not in document["scenario"]
    assert "obstacle_clearance" not in document["scenario"]
    assert not {"obstacle_distance_min", "closest_obstacle", "clear"} & set(
        document["verification"])


# --------------------------------------------------------------------------- verification


def _through_the_pillar(steps: int, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One vehicle at constant speed along y = 2.5 through x = 2.5 between two steps."""
    t = np.arange(steps + 1) * dt
    p = np.zeros((1, steps + 1, 3))
    p[0, :, 0] = 0.5 + 4.0 * t / t[-1]
    p[0, :, 1], p[0, :, 2] = 2.5, 1.5
    v = np.zeros_like(p)
    v[0, :, 0] = 4.0 / t[-1]
    return p, v, np.zeros((1, steps, 3))


def test_verification_catches_a_pass_through_an_obstacle_between_steps() -> None:
    data = _with([PILLAR], steps=4, dt=1.0)
    data["vehicles"] = [{"id": "solo", "start": [0.5, 2.5, 1.5], "goal": [4.5, 2.5, 1.5]}]
    scenario = planner.Scenario.from_dict(data)
    # Every step clear of the pillar (x = 1.5 and 3.5 are 0.7 m from its surface); the step
    # between them, at 2 m/s, goes through its axis at t = 1.5 s.
    p = np.zeros((1, 5, 3))
    p[0, :, 0] = [0.5, 1.5, 3.5, 4.0, 4.5]
    p[0, :, 1:] = [2.5, 1.5]
    v, a = np.zeros_like(p), np.zeros((1, 4, 3))
    v[0, 1, 0] = 2.0
    check = verify(scenario, p, v, a)
    assert not check.clear and not check.verified
    assert check.obstacle_distance_min == pytest.approx(-0.3, abs=1e-6)
    assert check.closest_obstacle == {"id": "pillar", "vehicle": "solo",
                                      "time": pytest.approx(1.5, abs=1e-6)}
    assert any("'pillar'" in failure for failure in check.failures())


def test_a_plan_that_grazes_the_clearance_is_never_converged(monkeypatch) -> None:
    """`plan` reports a plan whose verification finds an obstacle too close as unverified,
    whatever the loop said."""
    import planner.methods.stages as stages
    import planner.planning as planning
    from planner.scp.loop import ScpOutcome

    data = _with([PILLAR])
    data["vehicles"] = [{"id": "solo", "start": [0.5, 2.5, 1.5], "goal": [4.5, 2.5, 1.5]}]
    scenario = planner.Scenario.from_dict(data)
    p, v, a = _through_the_pillar(scenario.steps, scenario.dt)

    def fake(*args: Any, **kwargs: Any) -> ScpOutcome:
        return ScpOutcome("converged", "cost changed by 0", p, v, a, [], 0.0)

    monkeypatch.setattr(stages, "run_scp", fake)
    result = planning.plan(scenario)
    assert result.status == "unverified" and "obstacle 'pillar'" in result.message


def test_the_reported_minimum_matches_dense_sampling_near_and_far() -> None:
    """The continuous-time figure equals a brute-force dense sampling of the exact motion,
    for a plan that grazes an obstacle and for one that stays metres away from another."""
    near = planner.plan(load_example("pillar-circle8"))
    far = planner.plan(_with([{"id": "crate", "box": {"min": [0.0, 0.0, 0.0],
                                                       "max": [0.3, 0.3, 0.3]}}]))
    for result in (near, far):
        assert result.ok, result.problems()
        scenario = result.scenario
        times = np.linspace(0.0, scenario.horizon, 20 * scenario.steps + 1)
        sample = result.sample(times).position.reshape(-1, 3)
        geometry = ObstacleSet.build(scenario.obstacles)
        dense = min(float(geometry.signed_distance(sample, np.full(len(sample), o)).min())
                    for o in range(len(geometry)))
        check = result.verification
        assert check is not None and check.obstacle_distance_min is not None
        assert check.obstacle_distance_min <= dense + 1e-9
        assert check.obstacle_distance_min == pytest.approx(dense, abs=2e-3)
    assert far.verification is not None and far.verification.obstacle_distance_min > 1.0
