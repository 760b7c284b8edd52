"""The dodged first linearisation point for crowded fixed-goal fleets (`planner.methods.dodge`)."""

from __future__ import annotations

import numpy as np
import pytest

import planner
import planner.methods.stages as stages
from planner.families.generators import sideways
from planner.methods.dodge import GAP, dodged_moves
from planner.options import PlanningOptions
from planner.scp.first_qp import straight_moves
from planner.scp.loop import run_scp

DODGE = PlanningOptions(dodge=True)


def _step_min(p: np.ndarray, scale: np.ndarray) -> float:
    q = p / scale
    d = np.linalg.norm(q[:, None] - q[None], axis=3)
    d[np.arange(len(q)), np.arange(len(q))] = np.inf
    return float(d.min())


def test_the_dodge_pushes_the_sideways_crowd_apart_and_keeps_the_ends():
    scenario = planner.Scenario.from_dict(sideways(36))
    base = straight_moves(scenario)
    scale = scenario.separation_scale
    assert _step_min(base[0], scale) < 0.5  # lattice order: the straight moves collide
    found = dodged_moves(scenario, base)
    assert found is not None
    (p, v, a), worst = found
    assert worst >= 0.95 * scenario.min_separation
    assert _step_min(p, scale) >= 0.95 * scenario.min_separation
    np.testing.assert_array_equal(p[:, 0], base[0][:, 0])  # held exactly
    np.testing.assert_array_equal(p[:, -1], base[0][:, -1])
    np.testing.assert_allclose(p[:, 0], scenario.starts, atol=1e-9)
    np.testing.assert_allclose(p[:, -1], scenario.goals, atol=1e-9)
    assert v.shape == base[1].shape and a.shape == base[2].shape
    assert np.isfinite(v).all() and np.isfinite(a).all()
    # dodges, not a new route: nobody strays far from its straight line
    assert np.abs(p - base[0]).max() < 4.0 * scenario.min_separation


def test_nothing_to_dodge_gives_none():
    data = sideways(4, spacing=6.0)
    scenario = planner.Scenario.from_dict(data)
    base = straight_moves(scenario)
    assert _step_min(base[0], scenario.separation_scale) > 1.0 + GAP
    assert dodged_moves(scenario, base) is None


def test_a_dodged_start_plans_a_verified_crowd_as_good_as_the_synchronised_one(monkeypatch):
    monkeypatch.setattr(stages, "DODGE_MIN_VEHICLES", 2)
    data = sideways(25)
    dodged = planner.plan(data, options=DODGE, method="whole")
    plain = planner.plan(data, method="whole")
    assert dodged.ok, dodged.message
    assert dodged.verification.min_separation_continuous >= 1.0 - 1e-4
    # a different start, a plan of the same quality (both local optima of the same problem)
    assert dodged.cost == pytest.approx(plain.cost, rel=1e-5)


def test_a_dodged_start_that_fails_falls_back_to_the_synchronised_moves(monkeypatch):
    monkeypatch.setattr(stages, "DODGE_MIN_VEHICLES", 2)
    guesses = []

    def failing_first(scenario, solver, options=None, progress=None, guess=None,
                      first_qp=None):
        guesses.append(guess)
        outcome = run_scp(scenario, solver, options, progress, guess, first_qp)
        if len(guesses) == 1:  # the dodged start "fails"
            outcome.status = "max_iterations"
        return outcome

    monkeypatch.setattr(stages, "run_scp", failing_first)
    plan = planner.plan(sideways(16), options=DODGE, method="whole")
    assert len(guesses) == 2
    assert guesses[0] is not None and guesses[1] is None
    assert plan.ok and plan.status == "converged", plan.message


def test_small_fleets_and_the_default_keep_the_synchronised_start(monkeypatch):
    calls = []
    monkeypatch.setattr(stages, "dodged_moves", lambda *args: calls.append(1))
    assert planner.plan(sideways(16), options=DODGE, method="whole").ok  # under 64
    monkeypatch.setattr(stages, "DODGE_MIN_VEHICLES", 2)
    assert planner.plan(sideways(16), method="whole").ok  # off by default
    assert not calls
