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
