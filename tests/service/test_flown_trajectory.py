"""The plans a replanned flight flies, sampled on one flight-time grid: each vehicle on the
plan in force, a dropped one at rest where its plan left it, the switched replans read back
from a flight record."""

from __future__ import annotations

import numpy as np
import pytest

from gcs.errors import InvalidRequest
from gcs.service.flown_trajectory import flown_trajectory, replanned_in
from gcs.service.replan_handle import Segment
from planner import Plan
from tests.flight.support import line_scenario, smooth_plan

SWITCH = 2.05  # between two samples at 10 Hz: the grid is the flight's, not the replan's


@pytest.fixture(scope="module")
def plans() -> tuple[Plan, Plan]:
    """Three vehicles flying 2 m along y in 6 s; then, from SWITCH, uav1 and uav2 (listed
    the other way round) flying on from where the first plan had them, uav1 to a new goal
    and uav3 dropped."""
    first = smooth_plan(line_scenario(3))
    where = first.sample([SWITCH]).position[:, 0]
    scenario = line_scenario(2, steps=20)
    scenario["limits"] = first.scenario.to_dict()["limits"]
    uav1, uav2 = scenario["vehicles"]
    uav1.update(start=where[0].tolist(), goal=[2.0, 2.0, 2.5])
    uav2.update(start=where[1].tolist(), goal=first.scenario.vehicles[1].goal.tolist())
    scenario["vehicles"] = [uav2, uav1]
    return first, smooth_plan(scenario)


def test_each_vehicle_follows_the_plan_in_force(plans: tuple[Plan, Plan]) -> None:
    first, second = plans
    doc = flown_trajectory([Segment(SWITCH, second, 1), Segment(0.0, first)], 10.0, 10_000)
    t = np.array(doc["t"])
    end = SWITCH + second.scenario.horizon
    assert t[0] == 0.0 and t[-1] == pytest.approx(end)
    np.testing.assert_allclose(np.diff(t[:-1]), 0.1)
    assert [v["id"] for v in doc["vehicles"]] == ["uav1", "uav2", "uav3"]  # the first's order
    before, after = t < SWITCH, t >= SWITCH
    for n, vehicle in enumerate(doc["vehicles"][:2]):
        position = np.array(vehicle["position"])
        np.testing.assert_allclose(position[before], first.sample(t[before]).position[n])
        k = second.scenario.ids.index(vehicle["id"])
        np.testing.assert_allclose(position[after],
                                   second.sample(t[after] - SWITCH).position[k], atol=1e-12)
    np.testing.assert_allclose(doc["vehicles"][0]["position"][-1], [2.0, 2.0, 2.5])
    assert doc["switches"] == [{"replan": 1, "t": SWITCH}]


def test_the_flight_ends_with_the_plan_flown_last(plans: tuple[Plan, Plan]) -> None:
    first, _ = plans
    short = smooth_plan(line_scenario(3, steps=10))
    doc = flown_trajectory([Segment(0.0, first), Segment(SWITCH, short, 1)], 10.0, 10_000)
    assert doc["t"][-1] == pytest.approx(SWITCH + 2.0)  # not the first plan's 6 s


def test_a_dropped_vehicle_rests_where_its_plan_left_it(plans: tuple[Plan, Plan]) -> None:
    first, second = plans
    doc = flown_trajectory([Segment(0.0, first), Segment(SWITCH, second, 1)], 10.0, 10_000)
    t = np.array(doc["t"])
    uav3 = doc["vehicles"][2]
    position, velocity = np.array(uav3["position"]), np.array(uav3["velocity"])
    left = first.sample([SWITCH]).position[2, 0]
    np.testing.assert_allclose(position[t >= SWITCH], np.broadcast_to(left, (sum(t >= SWITCH), 3)))
    assert not velocity[t >= SWITCH].any()
    np.testing.assert_allclose(position[t < SWITCH], first.sample(t[t < SWITCH]).position[2])
    assert doc["dropped"] == {"uav3": SWITCH}


def test_without_replans_it_is_the_plan(plans: tuple[Plan, Plan]) -> None:
    first, _ = plans
    doc = flown_trajectory([Segment(0.0, first)], 5.0, 10_000)
    t = np.array(doc["t"])
    assert t[-1] == pytest.approx(first.scenario.horizon)
    for n, vehicle in enumerate(doc["vehicles"]):
        np.testing.assert_allclose(vehicle["position"], first.sample(t).position[n])
        np.testing.assert_allclose(vehicle["velocity"], first.sample(t).velocity[n])
    assert doc["switches"] == [] and doc["dropped"] == {}


def test_the_sample_count_is_bounded(plans: tuple[Plan, Plan]) -> None:
    first, second = plans
    with pytest.raises(InvalidRequest) as refused:
        flown_trajectory([Segment(0.0, first), Segment(SWITCH, second, 1)], 100.0, 1000)
    assert refused.value.field == "rate"
    assert "more than the limit 1000 (setting max_trajectory_samples)" in refused.value.reason


def test_switched_replans_are_read_from_a_flight_record(plans: tuple[Plan, Plan]) -> None:
    _, second = plans
    record = {"replans": [
        {"id": 1, "status": "missed", "switch_time": 1.0, "plan": None},
        {"id": 2, "status": "switched", "switch_time": SWITCH, "plan": second.to_dict()}]}
    [segment] = replanned_in(record)
    assert (segment.start, segment.replan) == (SWITCH, 2)
    assert segment.plan.scenario.ids == second.scenario.ids
    np.testing.assert_allclose(segment.plan.positions(), second.positions())
    assert replanned_in({"format": "fleetplan-flight-record/1"}) == []
