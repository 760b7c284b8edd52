"""planner.methods.landing: landing plans from a flying fleet's state, verified, R apart to the
ground."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import planner
from planner.errors import ScenarioError
from planner.methods.landing import (
    COLUMN_GRID,
    START_SLACK,
    TOUCHDOWN_SLACK,
    LandingError,
    escape_points,
    first_step_clearance,
    plan_landing,
    touchdown_points,
)
from planner.model.fixed import CLEARANCE_RAMP_S, landing_motion, relief_at
from planner.model.scenario import Scenario
from planner.verification.verify import SEPARATION_TOLERANCE
from tests.planner.conftest import load_example

STACKED = np.array([[2.0, 2.0, 1.08], [2.55, 2.0, 1.92]])


@pytest.fixture(scope="module")
def circle8():
    plan = planner.plan(load_example("paper-circle8"))
    assert plan.ok
    return plan


def test_touchdown_points_of_stacked_vehicles_are_side_by_side(circle8) -> None:
    """Two vehicles 0.55 m apart horizontally land R (and the slack) apart, each near below
    itself, at the landing height."""
    points = touchdown_points(STACKED, circle8.scenario, 0.3)
    gap = np.linalg.norm(points[0, :2] - points[1, :2])
    assert gap >= 1.0 * (1.0 + TOUCHDOWN_SLACK) - 1e-9
    assert gap < 1.2  # moved no more than needed
    np.testing.assert_allclose(points[:, 2], 0.3)
    assert np.all(np.linalg.norm(points[:, :2] - STACKED[:, :2], axis=1) < 0.5)


def test_a_floor_too_small_for_the_fleet_is_refused(circle8) -> None:
    """36 vehicles cannot stand 1.05 m apart on a 5 x 5 m floor: a LandingError says so."""
    grid = np.stack(np.meshgrid(np.linspace(0.5, 4.5, 6), np.linspace(0.5, 4.5, 6)), -1)
    crowd = np.concatenate([grid.reshape(-1, 2), np.full((36, 1), 2.0)], axis=1)
    with pytest.raises(LandingError, match="too crowded"):
        touchdown_points(crowd, circle8.scenario, 0.0)


@pytest.mark.parametrize("t", [4.0, 12.0, 15.0, 22.0])
def test_landing_from_the_paper_circle_mid_flight_keeps_r(circle8, t: float) -> None:
    """From the 8-vehicle circle's state (positions, velocities, accelerations) at t, the
    landing plan starts in that state, ends at rest on the floor R apart, and keeps R (less
    the start slack where the fleet is within a hair of R) over continuous time, verified."""
    state = circle8.sample(np.array([t]))
    p, v, a = (x[:, 0] for x in state)
    landing = plan_landing(circle8.scenario, p, v, a)
    plan = landing.plan
    assert plan.ok, plan.problems()
    assert landing.separation >= 1.0 - START_SLACK - 1e-9
    assert plan.verification.min_separation_continuous >= landing.separation - SEPARATION_TOLERANCE
    np.testing.assert_allclose(plan.positions()[:, 0], p, atol=1e-6)
    np.testing.assert_allclose(plan.velocities()[:, 0], v, atol=1e-6)
    np.testing.assert_allclose(plan.positions()[:, -1, 2], 0.0, atol=1e-6)
    assert np.abs(plan.velocities()[:, -1]).max() < 1e-6


def test_landing_a_stacked_pair_moves_the_lower_one_aside(circle8) -> None:
    """Landing each straight down would bring them 0.55 m apart; the plan keeps 1 m (less
    the 1 % start slack: they start 1.004 m apart)."""
    landing = plan_landing(circle8.scenario, STACKED, np.zeros((2, 3)), np.zeros((2, 3)),
                           ids=["low", "high"], landing_height=0.3)
    assert landing.plan.ok
    assert landing.separation == pytest.approx(1.0 - START_SLACK)
    assert landing.plan.verification.min_separation_continuous >= 0.99 - SEPARATION_TOLERANCE
    assert landing.plan.scenario.ids == ["low", "high"]


def test_a_fleet_already_closer_than_r_keeps_what_it_has(circle8) -> None:
    """Vehicles measured 0.9 m apart cannot be planned apart in no time: the landing keeps
    their 0.9 m (less the start slack, and says so) rather than fail."""
    points = np.array([[1.0, 1.0, 2.0], [1.9, 1.0, 2.0], [4.0, 4.0, 1.0]])
    landing = plan_landing(circle8.scenario, points, np.zeros((3, 3)), np.zeros((3, 3)),
                           ids=["a", "b", "c"])
    assert landing.separation == pytest.approx(0.9 - START_SLACK, abs=1e-6)
    assert landing.plan.ok
    assert landing.plan.verification.min_separation_continuous >= 0.89 - SEPARATION_TOLERANCE


def test_first_step_clearance_of_a_pair_passing_at_r() -> None:
    """Two vehicles passing each other side by side at R keep R along their first step's
    chord (d0's own direction would cut the step's end); two closing in head-on do not."""
    scenario = planner.Scenario.from_dict(load_example("paper-circle2"))
    p = np.array([[2.0, 2.0, 1.5], [3.0, 2.0, 1.5]])
    a = np.zeros((2, 3))
    passing = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    assert first_step_clearance(p, passing, a, scenario) == pytest.approx(1.0, abs=1e-6)
    closing = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    assert first_step_clearance(p, closing, a, scenario) == pytest.approx(
        1.0 - scenario.dt, abs=1e-6)


def test_bad_inputs_are_landing_errors(circle8) -> None:
    zeros = np.zeros((2, 3))
    with pytest.raises(LandingError, match="not finite"):
        plan_landing(circle8.scenario, np.full((2, 3), np.nan), zeros, zeros, ids=["a", "b"])
    with pytest.raises(LandingError, match="agree in length"):
        plan_landing(circle8.scenario, STACKED, zeros, zeros)


def test_vehicles_nearly_touching_are_a_landing_error(circle8) -> None:
    """Two vehicles 4 mm apart leave no separation a scenario can hold (it would be
    negative): a LandingError saying so, for the caller's fallback, not a ScenarioError."""
    points = np.array([[1.0, 1.0, 2.0], [1.004, 1.0, 2.0]])
    zeros = np.zeros((2, 3))
    with pytest.raises(LandingError, match="too close to plan a landing"):
        plan_landing(circle8.scenario, points, zeros, zeros, ids=["a", "b"])


@pytest.fixture(scope="module")
def shelving16():
    from planner.families.obstacle_generators import shelving

    plan = planner.plan(planner.Scenario.from_dict(shelving(16, seed=0)))
    assert plan.ok
    return plan


@pytest.mark.parametrize("t", [4.0, 10.0, 14.0])
def test_a_landing_among_shelving_keeps_its_clearance_and_lands_beside_them(
    shelving16, t: float
) -> None:
    """The warehouse's shelves are in the landing's scenario too: from the fleet's state at t
    (at 14 s five vehicles fly over the shelves' tops) the landing keeps the flight's own
    obstacle clearance over continuous time, and every touchdown point's column is clear of
    the shelves' footprints (PX4's Land descends there), while R is kept as before."""
    scenario = shelving16.scenario
    p, v, a = (x[:, 0] for x in shelving16.sample(np.array([t])))
    landing = plan_landing(scenario, p, v, a)
    plan = landing.plan
    assert plan.ok, plan.problems()
    assert [o.id for o in plan.scenario.obstacles] == [o.id for o in scenario.obstacles]
    assert plan.scenario.clearance == scenario.clearance
    assert plan.verification.obstacle_distance_min >= scenario.clearance - 1e-4
    assert plan.verification.min_separation_continuous >= landing.separation - SEPARATION_TOLERANCE
    touchdown = plan.positions()[:, -1]
    geometry = scenario.obstacle_set
    n, m = len(touchdown), len(geometry)
    footprint, _, _ = geometry.horizontal(np.repeat(touchdown[:, :2], m, axis=0),
                                          np.tile(np.arange(m), n))
    assert footprint.min() >= scenario.clearance - 1e-9


def test_touchdown_points_leave_an_obstacle_they_fall_in(shelving16) -> None:
    """A vehicle hovering over a shelf gets a touchdown point beside it, the clearance (and
    its slack) from the shelf's footprint; one in the aisle keeps the point below it."""
    scenario = shelving16.scenario
    shelf = scenario.obstacle_set
    over = np.array([[10.0, 0.5 * (shelf.lo[1, 1] + shelf.hi[1, 1]) + 0.1, 3.5],
                     [10.0, 0.5 * (shelf.hi[1, 1] + shelf.lo[2, 1]), 1.5]])
    points = touchdown_points(over, scenario, 0.0)
    gap = max(points[0, 1] - shelf.hi[1, 1], shelf.lo[1, 1] - points[0, 1])
    assert gap == pytest.approx(scenario.clearance * (1.0 + TOUCHDOWN_SLACK), rel=0.02)
    assert points[0, 1] > shelf.hi[1, 1]  # out by the nearer side (it was past the middle)
    np.testing.assert_allclose(points[1], [*over[1, :2], 0.0])


def test_a_vehicle_nearer_a_shelf_than_the_clearance_still_gets_a_landing(shelving16) -> None:
    """A vehicle measured a little inside the clearance (off its plan, or a plan at its
    closest within the verification's tolerance) cannot be put back outside in no time: the
    landing keeps what it has less 1 % of the clearance, instead of the whole fleet falling
    back to PX4's Land, and that smaller clearance is verified."""
    scenario = shelving16.scenario
    p, v, a = (x[:, 0] for x in shelving16.sample(np.array([4.0])))
    shelf = scenario.obstacle_set
    # uav1 moved 2 cm into the clearance of the first shelf's near face, at rest
    p = p.copy()
    p[0, :2] = [10.0, shelf.lo[0, 1] - scenario.clearance + 0.02]
    p[0, 2] = 1.5
    v, a = v.copy(), a.copy()
    v[0] = a[0] = 0.0
    landing = plan_landing(scenario, p, v, a)
    kept = landing.plan.scenario.clearance
    assert kept == pytest.approx(scenario.clearance - 0.02 - 0.01 * scenario.clearance)
    assert landing.plan.ok, landing.plan.problems()
    assert landing.plan.verification.obstacle_distance_min >= kept - 1e-4


def _lost_at_8s(circle8, *, margin: float, hold_s: float) -> tuple:
    """The circle's state at 8 s, uav2 (over uav1) lost there: p, v, a of all, its predicted
    landing (braking, `hold_s`, straight down), the others' indices and ids."""
    state = circle8.sample(np.array([8.0]))
    p, v, a = (x[:, 0] for x in state)
    lost = landing_motion("uav2", p[1], v[1], circle8.scenario.dt, 2.0, 0.7, 0.0,
                          margin=margin, hold_s=hold_s)
    others = [n for n in range(8) if n != 1]
    return p, v, a, lost, others, [circle8.scenario.ids[n] for n in others]


def test_a_landing_keeps_r_plus_margin_from_a_vehicle_on_its_own_failsafe(circle8) -> None:
    """One vehicle of the circle is lost at t = 8 s: it holds 5 s where it is, then lands
    straight down (a fixed trajectory with a 0.3 m margin). The other seven land by a plan
    that keeps R + 0.3 m from it over continuous time, touch down R + 0.3 m (and the slack)
    from where it rests, and last until it is down; without it, the plan would not."""
    p, v, a, lost, others, ids = _lost_at_8s(circle8, margin=0.3, hold_s=5.0)
    landing = plan_landing(circle8.scenario, p[others], v[others], a[others], ids=ids,
                           fixed=[lost])
    plan = landing.plan
    assert plan.ok, plan.problems()
    verification = plan.verification
    assert verification.fixed_distance_min >= 1.0 - SEPARATION_TOLERANCE  # margin ramps in
    assert verification.closest_fixed["id"] == "uav2"
    assert plan.scenario.horizon >= (len(lost) - 1) * plan.scenario.dt - 1e-9
    rest = lost.positions[-1, :2]
    gaps = np.linalg.norm(plan.positions()[:, -1, :2] - rest, axis=1)
    assert gaps.min() >= 1.3 * (1.0 + TOUCHDOWN_SLACK) - 1e-9
    # the hold lasts 5 s at its stop point, then it goes straight down to the floor
    stop = lost.positions[-1]
    held = np.flatnonzero(np.all(np.abs(lost.positions - stop * [1, 1, 0]
                                        - [0, 0, lost.positions[:, 2].max()]) < 1e-9, axis=1))
    assert len(held) * circle8.scenario.dt >= 5.0
    plain = touchdown_points(p[others], circle8.scenario, 0.0)
    assert np.linalg.norm(plain[:, :2] - rest, axis=1).min() < 1.3  # it mattered


def test_a_vehicle_starting_near_a_lost_one_keeps_what_it_starts_with(circle8) -> None:
    """A vehicle at rest 0.9 m from a fixed one (a lost vehicle holding there) cannot be
    R away at once: that pair alone keeps the 0.9 m it starts with (less the start slack),
    growing back to R within CLEARANCE_RAMP_S after the first step, verified; the other
    vehicle, and the pair of them, keep the full R."""
    scenario = circle8.scenario
    lost = landing_motion("lost", [2.0, 2.0, 1.5], np.zeros(3), scenario.dt, 2.0,
                          0.7, 0.0, hold_s=4.0)
    p = np.array([[2.9, 2.0, 1.5], [2.9, 3.4, 1.5]])
    landing = plan_landing(scenario, p, np.zeros((2, 3)), np.zeros((2, 3)),
                           ids=["near", "far"], fixed=[lost])
    plan = landing.plan
    assert plan.ok, plan.problems()
    assert landing.separation == scenario.min_separation  # the fleet keeps R
    [kept] = plan.scenario.fixed
    assert dict(kept.start_clearance) == {"near": pytest.approx(0.9 - START_SLACK, abs=1e-6)}
    assert plan.verification.fixed_distance_min >= 0.9 - START_SLACK - SEPARATION_TOLERANCE
    t = np.arange(0.0, plan.scenario.horizon, 0.005)
    predicted = lost.state(t, scenario.dt)[0]
    gap = np.linalg.norm(plan.sample(t).position - predicted[None], axis=2)
    after = t >= scenario.dt + CLEARANCE_RAMP_S
    assert gap[:, after].min() >= 1.0 - SEPARATION_TOLERANCE  # back to R, and stays
    ramp = 0.89 + 0.11 * (1.0 - relief_at(t, scenario.dt))
    assert (gap[0] >= ramp - SEPARATION_TOLERANCE).all()  # never below the ramp
    assert gap[1].min() >= 1.0 - SEPARATION_TOLERANCE  # the other one never relaxed
    gaps = np.linalg.norm(plan.positions()[:, -1, :2] - [2.0, 2.0], axis=1)
    assert gaps.min() >= 1.0 * (1.0 + TOUCHDOWN_SLACK) - 1e-9  # R from where it rests


def test_a_start_clearance_names_planned_vehicles_only() -> None:
    """A fixed trajectory's start_clearance is checked like the rest of the scenario: a
    planned vehicle's id and a positive distance, and a start it allows is refused below
    it."""
    base = {"name": "t", "dt": 0.2, "steps": 30, "min_separation": 1.0,
            "limits": {"position_min": [0, 0, 0], "position_max": [5, 5, 3]},
            "vehicles": [{"id": "a", "start": [1.0, 1.0, 1.0], "goal": [4.0, 4.0, 1.0]}]}
    lost = {"id": "x", "positions": [[1.0, 1.8, 1.0]]}
    with pytest.raises(ScenarioError) as error:
        Scenario.from_dict({**base, "fixed": [lost]})
    assert error.value.field == "vehicles[0].start"
    ok = Scenario.from_dict({**base, "fixed": [{**lost, "start_clearance": {"a": 0.75}}]})
    assert ok.fixed[0].to_dict()["start_clearance"] == {"a": 0.75}
    for clearance, field in (({"b": 0.5}, "fixed[0].start_clearance.b"),
                             ({"a": -1.0}, "fixed[0].start_clearance.a"),
                             ({"a": 0.85}, "vehicles[0].start"),
                             ([0.5], "fixed[0].start_clearance")):
        with pytest.raises(ScenarioError) as error:
            Scenario.from_dict({**base, "fixed": [{**lost, "start_clearance": clearance}]})
        assert error.value.field == field


def test_moving_away_first_clears_a_lost_vehicles_whole_column(circle8) -> None:
    """uav2 is lost over uav1 at 8 s (0.54 m aside horizontally): it holds 1 s, then comes
    down. A plan that moves the others away first (the landing's second stage) takes each
    to its own height, clear of every point uav2 passes by R + margin horizontally and R
    from the others, verified against uav2's motion; from there each goes straight down."""
    p, v, a, lost, others, ids = _lost_at_8s(circle8, margin=0.2, hold_s=1.0)
    away = plan_landing(circle8.scenario, p[others], v[others], a[others], ids=ids,
                        fixed=[lost], stages=("escape",))
    plan = away.plan
    assert plan.ok, plan.problems()
    assert not away.touchdown and away.separation == 1.0
    ends = plan.positions()[:, -1]
    assert np.allclose(ends[:, 2], p[others, 2], atol=1e-6)  # at their own heights
    column = lost.positions[:, :2]
    gaps = np.linalg.norm(ends[:, None, :2] - column[None], axis=2)
    assert gaps.min() >= 1.2 * (1.0 + TOUCHDOWN_SLACK) - COLUMN_GRID  # the whole column
    i, j = np.triu_indices(len(ends), k=1)
    assert np.linalg.norm(ends[i, :2] - ends[j, :2], axis=1).min() >= 1.0  # land side by side
    assert plan.verification.fixed_distance_min >= 1.0 - SEPARATION_TOLERANCE
    assert plan.scenario.horizon < (len(lost) - 1) * circle8.scenario.dt  # shorter than it
    # from there a landing keeps R + the whole margin from it (none is relaxed)
    rest = plan.sample(np.array([plan.scenario.horizon]))
    t_end = plan.scenario.horizon
    later = landing_motion("uav2", *lost.state(t_end, circle8.scenario.dt)[:2],
                           circle8.scenario.dt, 2.0, 0.7, 0.0, margin=0.2,
                           hold_s=max(0.0, 1.0 - t_end))
    down = plan_landing(circle8.scenario, rest.position[:, 0], rest.velocity[:, 0],
                        rest.acceleration[:, 0], ids=ids, fixed=[later])
    assert down.touchdown and down.plan.ok, down.plan.problems()
    assert not down.plan.scenario.fixed[0].start_clearance
    assert down.plan.verification.fixed_distance_min >= 1.0 - SEPARATION_TOLERANCE


def test_escape_points_of_vehicles_around_a_column() -> None:
    """Vehicles around a descending column are pushed out of it horizontally, at their own
    heights, the farther ones left where they are."""
    scenario = Scenario.from_dict({
        "name": "t", "dt": 0.2, "steps": 10, "min_separation": 1.0,
        "limits": {"position_min": [0, 0, 0], "position_max": [6, 6, 3]},
        "vehicles": [{"id": "a", "start": [1.0, 1.0, 1.0], "goal": [4.0, 4.0, 1.0]}]})
    column = landing_motion("L", [3.0, 3.0, 2.5], np.zeros(3), 0.2, 2.0, 0.7, 0.0,
                            margin=0.3)
    p = np.array([[3.0, 3.2, 1.0], [3.5, 3.0, 0.6], [0.5, 0.5, 2.0]])
    out = escape_points(p, scenario, 0.0, [column])
    assert np.array_equal(out[:, 2], p[:, 2])
    assert np.linalg.norm(out[:2, :2] - [3.0, 3.0], axis=1).min() >= 1.3 * 1.05 - 1e-6
    assert np.allclose(out[2], p[2])


def test_a_landing_whose_first_qp_has_no_solution_is_not_retried_longer() -> None:
    """paper-circle8 flown in 16 s (as on the mock), uav2 lost at 7.5 s with uav1 and uav3
    1.005 m from it: no landing opens the full 0.28 m margin in time, and its first QP says
    so. A longer horizon starts from the same state (and took 26 s of CPU to say the same),
    so the landing fails at once and the next share of the margin plans it."""
    circle8 = planner.plan(planner.Scenario.from_dict(
        {**load_example("paper-circle8"), "steps": 80}))
    assert circle8.ok
    state = circle8.sample(np.array([7.5]))
    p, v, a = (x[:, 0] for x in state)
    lost = landing_motion("uav2", p[1], v[1], circle8.scenario.dt, 2.0, 0.7, 0.0,
                          margin=0.28, hold_s=7.6, acceleration=a[1], coast_steps=1)
    others = [n for n in range(8) if n != 1]
    ids = [circle8.scenario.ids[n] for n in others]
    with pytest.raises(LandingError) as error:
        plan_landing(circle8.scenario, p[others], v[others], a[others], ids=ids,
                     fixed=[lost], stages=("landing",))
    assert str(error.value).count("status infeasible: iteration 1") == 1
    half = plan_landing(circle8.scenario, p[others], v[others], a[others], ids=ids,
                        fixed=[replace(lost, margin=0.14)], stages=("landing",))
    assert half.touchdown and half.plan.ok and half.attempts == 1
