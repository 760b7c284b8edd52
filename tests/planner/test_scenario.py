"""Scenario validation: every error names the field and says why."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from planner import Scenario, ScenarioError
from tests.planner.conftest import load_example


def _base() -> dict[str, Any]:
    return load_example("paper-circle4")


def _error(data: dict[str, Any]) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        Scenario.from_dict(data)
    return info.value


def test_valid_scenario_fills_defaults():
    data = _base()
    del data["cost_threshold"]
    scenario = Scenario.from_dict(data)
    echoed = scenario.to_dict()
    assert echoed["cost_threshold"] == 0.05
    assert echoed["separation_scale"] == [1.0, 1.0, 1.0]
    assert echoed["limits"]["thrust_max"] == 18.0
    assert Scenario.from_dict(echoed).to_dict() == echoed


def _mutate(path: list[Any], value: Any) -> dict[str, Any]:
    data = copy.deepcopy(_base())
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


@pytest.mark.parametrize(
    ("path", "value", "field", "reason"),
    [
        (["steps"], KeyError, "steps", "is required"),
        (["bogus"], 1, "bogus", "unknown key"),
        (["limits", "speed"], 1, "limits.speed", "unknown key"),
        (["vehicles", 0, "name"], "x", "vehicles[0].name", "unknown key"),
        (["dt"], -0.1, "dt", "must be positive"),
        (["dt"], "fast", "dt", "must be a number"),
        (["dt"], math.nan, "dt", "finite"),
        (["min_separation"], math.inf, "min_separation", "finite"),
        (["steps"], 10.5, "steps", "must be an integer"),
        (["steps"], 1, "steps", "between"),
        (["separation_scale"], [1, 1], "separation_scale", "3 numbers"),
        (["separation_scale"], [1, 0, 2], "separation_scale[1]", "positive"),
        (["limits", "position_max"], [5, 0, 3], "limits.position_max[1]", "greater than"),
        (["limits", "velocity_max"], [2, 2, -1], "limits.velocity_max[2]", "positive"),
        (["limits", "thrust_max"], 1.0, "limits.thrust_max", "greater than thrust_min"),
        (["vehicles"], [], "vehicles", "at least one"),
        (["vehicles", 0, "id"], "", "vehicles[0].id", "non-empty string"),
        (["vehicles", 1, "id"], "uav1", "vehicles[1].id", "duplicate id 'uav1'"),
        (["vehicles", 2, "start"], [0.5, 2.5, math.nan], "vehicles[2].start[2]", "finite"),
        (["vehicles", 0, "start"], [6.0, 2.5, 1.1], "vehicles[0].start", "outside the workspace"),
        (["vehicles", 3, "goal"], [2.0, 4.0, -1.0], "vehicles[3].goal", "outside the workspace"),
        (["vehicles", 1, "start"], [4.5, 2.6, 1.2], "vehicles[1].start", "closer than"),
        (["vehicles", 1, "goal"], [0.6, 2.2, 1.2], "vehicles[1].goal", "closer than"),
    ],
)
def test_invalid_scenarios_name_field_and_reason(path, value, field, reason):
    error = _error(_mutate(path, value))
    assert error.field == field
    assert reason in error.reason
    assert error.to_dict() == {"field": field, "reason": error.reason}


def test_horizon_too_short_names_the_vehicle_and_the_time_needed():
    data = _base()
    data["steps"] = 10  # 2 s, but uav1 moves ~4 m under |v| <= 2, |a| <= 3
    error = _error(data)
    assert error.field.startswith("vehicles[")
    assert error.field.endswith(".goal")
    assert "cannot be reached within the horizon" in error.reason
    assert "2.00 s" in error.reason


def test_separation_scale_changes_which_starts_are_too_close():
    data = _base()
    data["vehicles"][1]["start"] = [4.5, 2.5, 2.3]  # 1.2 m above uav1: fine for a sphere
    Scenario.from_dict(data)
    data["separation_scale"] = [1.0, 1.0, 2.0]  # ellipsoid: 1.2 / 2 = 0.6 < 1
    assert _error(data).field == "vehicles[1].start"


def test_not_an_object():
    assert _error([1, 2]).field == "scenario"  # type: ignore[arg-type]


HUGE_INT = 10**400  # beyond any float: float(HUGE_INT) raises OverflowError
SUBNORMAL = 5e-324


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        (["separation_scale"], [1e-300, 1e-300, 1e-300], "separation_scale[0]"),
        (["separation_scale"], [1.0, 1.0, 1e300], "separation_scale[2]"),
        (["separation_scale"], [1.0, SUBNORMAL, 1.0], "separation_scale[1]"),
        (["separation_scale"], [1.0, 1.0, HUGE_INT], "separation_scale[2]"),
        (["dt"], 1e-300, "dt"),
        (["dt"], 1e300, "dt"),
        (["dt"], HUGE_INT, "dt"),
        (["dt"], -0.0, "dt"),
        (["steps"], HUGE_INT, "steps"),
        (["steps"], 1e300, "steps"),
        (["steps"], -0.0, "steps"),
        (["min_separation"], SUBNORMAL, "min_separation"),
        (["min_separation"], 1e300, "min_separation"),
        (["min_separation"], HUGE_INT, "min_separation"),
        (["cost_threshold"], 1e-300, "cost_threshold"),
        (["cost_threshold"], 1e300, "cost_threshold"),
        (["max_iterations"], HUGE_INT, "max_iterations"),
        (["max_iterations"], 1e300, "max_iterations"),
        (["separation_margin"], HUGE_INT, "separation_margin"),
        (["limits", "position_min"], [-1e300, 0.0, 0.0], "limits.position_min[0]"),
        (["limits", "position_max"], [5.0, HUGE_INT, 3.0], "limits.position_max[1]"),
        (["limits", "velocity_max"], [1e-300, 2.0, 2.0], "limits.velocity_max[0]"),
        (["limits", "velocity_max"], [2.0, 1e300, 2.0], "limits.velocity_max[1]"),
        (["limits", "acceleration_max"], [3.0, 3.0, SUBNORMAL], "limits.acceleration_max[2]"),
        (["limits", "acceleration_max"], [HUGE_INT, 3.0, 3.0], "limits.acceleration_max[0]"),
        (["limits", "jerk_max"], [5.0, 1e300, 5.0], "limits.jerk_max[1]"),
        (["limits", "jerk_max"], [5.0, 5.0, 1e-300], "limits.jerk_max[2]"),
        (["limits", "thrust_min"], 1e300, "limits.thrust_min"),
        (["limits", "thrust_max"], 1e300, "limits.thrust_max"),
        (["limits", "thrust_max"], HUGE_INT, "limits.thrust_max"),
        (["limits", "body_rate_max"], 1e-300, "limits.body_rate_max"),
        (["limits", "body_rate_max"], 1e300, "limits.body_rate_max"),
        (["vehicles", 0, "start"], [4.5, 2.5, HUGE_INT], "vehicles[0].start[2]"),
        (["vehicles", 2, "goal"], [1e300, 2.5, 1.1], "vehicles[2].goal[0]"),
    ],
    ids=lambda x: "huge-int" if x is HUGE_INT else None,
)
def test_numbers_outside_their_sane_range_are_refused(path, value, field):
    """No magnitude switches a check off or overflows what is derived from it: every number
    has a range, and a value outside it is an error naming the field and the range."""
    error = _error(_mutate(path, value))
    assert error.field == field
    assert "must be" in error.reason
    assert len(error.reason) < 200  # a huge integer is not printed digit by digit


@pytest.mark.parametrize(
    "changes",
    [
        {"separation_scale": [0.1, 0.1, 0.1]},
        {"separation_scale": [10.0, 10.0, 10.0], "min_separation": 0.1},
        {"dt": 0.05, "steps": 5000},
        {"cost_threshold": 1e-9},
        {"max_iterations": 1000.0},
        {"min_separation": 0.01},
    ],
)
def test_numbers_at_the_ends_of_their_ranges_are_accepted(changes):
    data = _base() | changes
    data["limits"]["position_min"] = [-0.0, 0.0, -0.0]  # negative zero is zero
    Scenario.from_dict(data)


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        (["vehicles", 1, "id"], "uav\x002", "vehicles[1].id"),
        (["vehicles", 0, "id"], "uav1\r\n=cmd", "vehicles[0].id"),
        (["vehicles", 2, "id"], "\tuav3", "vehicles[2].id"),
        (["vehicles", 3, "id"], "uav\x1b[31m4", "vehicles[3].id"),
        (["vehicles", 3, "id"], "uav\x7f", "vehicles[3].id"),
        (["vehicles", 3, "id"], "uav\u202e4", "vehicles[3].id"),  # bidi override
        (["vehicles", 3, "id"], "u" * 65, "vehicles[3].id"),
    ],
)
def test_vehicle_ids_with_control_characters_are_refused(path, value, field):
    error = _error(_mutate(path, value))
    assert error.field == field
    assert "character" in error.reason or "at most" in error.reason


def test_printable_ids_are_kept_as_given():
    data = _mutate(["vehicles", 0, "id"], "=uav 1 ü")
    assert Scenario.from_dict(data).ids[0] == "=uav 1 ü"


def test_the_planner_takes_a_record_sized_fleet_and_refuses_one_beyond_its_bound() -> None:
    """A record drone show is ~16,000 vehicles: the planner's own bound is 20,000 (a service
    sets a lower one, `max_vehicles`). Its starts and goals are checked for separation in
    about a second (a k-d tree; all pairs would be 128 million distances)."""
    def fleet(count: int) -> dict[str, Any]:
        data = _base()
        side = math.ceil(math.sqrt(count))
        data["limits"] = {**data["limits"], "position_min": [-1.0, -1.0, 0.0],
                          "position_max": [2.0 * side + 1, 2.0 * side + 1, 10.0]}
        data["steps"], data["dt"] = 60, 0.5
        data["vehicles"] = [{"id": f"v{i}", "start": [2.0 * (i % side), 2.0 * (i // side), 1.0],
                             "goal": [2.0 * (i % side), 2.0 * (i // side), 3.0]}
                            for i in range(count)]
        return data

    assert len(Scenario.from_dict(fleet(16_000)).vehicles) == 16_000
    error = _error(fleet(20_001))
    assert error.field == "vehicles" and error.reason == "at most 20000 vehicles, got 20001"
    crowded = fleet(16_000)
    crowded["vehicles"][9_000]["goal"] = [crowded["vehicles"][12_345]["goal"][0] + 0.3,
                                          *crowded["vehicles"][12_345]["goal"][1:]]
    error = _error(crowded)  # the pair closer than R is still found, and named
    assert error.field == "vehicles[12345].goal"
    assert error.reason.startswith("is 0.300 m from vehicles[9000].goal")
