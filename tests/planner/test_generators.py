"""Scenario generators, including the dmpc2019 benchmark distribution."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import planner
from planner.generators import (
    circle_swap,
    dmpc2019_points,
    dmpc2019_scenario,
    random_transitions,
)

PUBLISHED = Path(__file__).resolve().parents[2] / "bench" / "dmpc2019-published.json"


def test_dmpc2019_generator_reproduces_the_authors_stored_trial():
    stored = json.loads(PUBLISHED.read_text())["stored_last_trial"]
    stream = np.random.RandomState(5489)  # MATLAB's default Mersenne Twister
    stream.random_sample(1_114_470)  # the draws made before that trial (see the README)
    starts = dmpc2019_points(stream.random_sample, stored["N"])
    goals = dmpc2019_points(stream.random_sample, stored["N"])
    np.testing.assert_array_equal(starts, stored["start"])
    np.testing.assert_array_equal(goals, stored["goal"])


def test_dmpc2019_scenarios_follow_the_benchmark_parameters():
    data = dmpc2019_scenario(12, seed=1, trial=4)
    scenario = planner.Scenario.from_dict(data)
    assert scenario.steps == 50 and scenario.dt == 0.2
    assert scenario.limits.velocity_max is None and scenario.limits.jerk_max is None
    np.testing.assert_array_equal(scenario.limits.acceleration_max, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(scenario.separation_scale, [1.0, 1.0, 2.0])
    assert dmpc2019_scenario(12, seed=1, trial=4) == data  # deterministic
    assert dmpc2019_scenario(12, seed=1, trial=5) != data


def test_other_generators_give_valid_scenarios():
    for data in (circle_swap(10), random_transitions(20, seed=2)):
        scenario = planner.Scenario.from_dict(data)
        assert len(scenario.vehicles) == len(data["vehicles"])
