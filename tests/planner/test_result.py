"""The Plan JSON contract: written, read back, and malformed documents named precisely."""

from __future__ import annotations

import json

import numpy as np
import pytest

import planner
from planner import Plan, PlanFormatError
from tests.planner.conftest import load_example


@pytest.fixture(scope="module")
def plan() -> Plan:
    return planner.plan(load_example("paper-random4"))


def test_round_trip_through_json(plan):
    text = json.dumps(plan.to_dict())
    again = Plan.from_dict(json.loads(text))
    assert again.to_dict() == plan.to_dict()
    np.testing.assert_array_equal(again.positions(), plan.positions())


def test_contract_keys(plan):
    doc = plan.to_dict()
    assert {"status", "scenario", "iterations", "timing", "vehicles", "verification"} <= set(doc)
    assert set(doc["timing"]) >= {"total_s", "first_qp_s"}
    k = plan.scenario.steps
    vehicle = doc["vehicles"][0]
    assert len(vehicle["t"]) == len(vehicle["position"]) == len(vehicle["velocity"]) == k + 1
    assert len(vehicle["acceleration"]) == len(vehicle["jerk"]) == len(vehicle["thrust"]) == k
    assert len(vehicle["body_rates"][0]) == 3
    assert {"min_separation", "min_separation_continuous", "max_violation", "boundary_error",
            "flyable"} <= set(doc["verification"])
    assert doc["iterations"][0]["iteration"] == 0


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.pop("vehicles"), "vehicles"),
        (lambda d: d.update(status="done"), "status"),
        (lambda d: d["vehicles"][1].update(id="other"), "vehicles[1].id"),
        (lambda d: d["vehicles"][2]["position"].pop(), "vehicles[2].position"),
        (lambda d: d["vehicles"][0]["velocity"][3].__setitem__(1, "x"), "vehicles[0].velocity"),
        (lambda d: d["scenario"].update(dt=-1), "scenario.dt"),
    ],
)
def test_malformed_plans_name_the_field(plan, edit, field):
    doc = json.loads(json.dumps(plan.to_dict()))
    edit(doc)
    with pytest.raises(PlanFormatError) as info:
        Plan.from_dict(doc)
    assert info.value.field == field


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["verification"].update(extra=1), "verification.extra"),
        (lambda d: d.update(iterations={"a": 1}), "iterations"),
        (lambda d: d["iterations"][0].pop("cost"), "iterations[0]"),
        (lambda d: d["timing"].update(total_s="fast"), "timing.total_s"),
    ],
)
def test_malformed_optional_blocks_name_the_field(plan, edit, field):
    doc = json.loads(json.dumps(plan.to_dict()))
    edit(doc)
    with pytest.raises(PlanFormatError) as info:
        Plan.from_dict(doc)
    assert info.value.field == field


def test_a_plan_beyond_the_flyability_limits_is_not_verified():
    data = load_example("paper-circle4")
    data["limits"]["body_rate_max"] = 0.001
    plan = planner.plan(data)
    assert plan.status == "unverified"
    assert not plan.ok and not plan.verification.flyable
    assert "not flyable" in plan.message
