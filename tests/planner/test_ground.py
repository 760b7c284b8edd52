"""Takeoff from and landing on a ground grid tighter than R: staggered waves, every pair in
the air kept R apart (checked here by sampling, independently of the verifier), the ground
rule applied only to a show that declares it, and the .skyc's takeoffTime and landing."""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np
import pytest

from gcs.export.skyc import skyc_chunks
from planner import Plan
from planner.errors import ScenarioError
from planner.families.generators import show_sequence
from planner.methods.sequence import SequencePlan, parse_sequence, plan_sequence
from planner.verification.verify import refusal
from tests.export.reader import evaluate, read_show
from tests.support.shows import GRID
from tests.support.shows import ground_show as _show

#: Rows 0.8 m apart (R = 1): neighbours in y must not share a wave.


@pytest.fixture(scope="module")
def shown() -> SequencePlan:
    result = plan_sequence(_show(landing={}))
    assert result.ok, result.message
    return result


def test_it_starts_and_ends_on_the_grid(shown: SequencePlan) -> None:
    homes = np.array([[-2 + 2 * c, -2 + 0.8 * r, 0.0] for r in range(3) for c in range(3)])
    p = shown.positions
    assert np.abs(p[:, 0] - homes).max() == 0.0
    landed = p[:, -1]
    assert np.abs(landed[:, 2]).max() < 1e-6
    # free landing: every drone on a different home of the grid
    slot = [int(np.argmin(np.linalg.norm(homes - q, axis=1))) for q in landed]
    assert sorted(slot) == list(range(9))
    assert np.abs(landed - homes[slot]).max() < 1e-6
    assert shown.segments[0]["kind"] == "takeoff"
    assert shown.segments[-1]["kind"] == "landing"


def test_rows_closer_than_r_take_off_in_turn(shown: SequencePlan) -> None:
    ground = shown.sequence.ground
    assert ground is not None
    wave = ground.takeoff_waves.reshape(3, 3)
    assert (wave[0] != wave[1]).all() and (wave[1] != wave[2]).all()
    liftoff, _ = shown.ground_steps
    z = shown.positions[:, :, 2]
    for n in range(9):
        # nobody is off the ground before its lift-off step
        assert np.abs(z[n, :liftoff[n] + 1]).max() == 0.0
    first = [n for n in range(9) if ground.takeoff_waves[n] == 0]
    second = [n for n in range(9) if ground.takeoff_waves[n] == 1]
    k = liftoff[second[0]]
    assert all(liftoff[n] == k for n in second) and all(liftoff[n] == 0 for n in first)
    # the first wave is up at its layer, at rest, when the second leaves the ground
    assert np.abs(z[first, k] - ground.liftoff[first, 2]).max() < 1e-6


def test_every_pair_in_the_air_keeps_r_sampled_independently(shown: SequencePlan) -> None:
    plan = shown.to_plan()
    times = np.linspace(0.0, plan.scenario.horizon, 8001)
    p = plan.sample(times).position  # (N, M, 3)
    up = p[:, :, 2] > 1e-6
    worst = np.inf
    for i in range(9):
        for j in range(i + 1, 9):
            both = up[i] & up[j]
            if both.any():
                worst = min(worst, float(np.linalg.norm(p[i, both] - p[j, both], axis=1).min()))
    assert worst >= 1.0 - 1e-4
    # On the ground the homes stand 0.8 m apart: the rule is what makes this a show.
    assert shown.verification.separated
    assert shown.verification.min_separation_continuous >= 1.0 - 1e-4


def test_the_ground_rule_holds_only_for_a_show_that_declares_it(shown: SequencePlan) -> None:
    plan = shown.to_plan()
    assert refusal(plan) is None
    undeclared = copy.deepcopy(plan.sequence)
    del undeclared["ground"]
    why = refusal(dataclasses.replace(plan, sequence=undeclared))
    assert why is not None and "separation" in why


def test_the_summary_says_who_flies_when(shown: SequencePlan) -> None:
    ground = shown.summary()["ground"]
    assert ground["takeoff"]["homes"]["uav1"] == [-2.0, -2.0, 0.0]
    assert set(ground["takeoff"]["waves"].values()) == {0, 1}
    assert min(ground["takeoff"]["liftoff_s"].values()) == 0.0
    assert max(ground["landing"]["touchdown_s"].values()) == pytest.approx(
        shown.duration - shown.sequence.dt)


def test_the_skyc_takes_off_at_takeoff_time_and_lands(shown: SequencePlan) -> None:
    plan = shown.to_plan()
    show = read_show(b"".join(skyc_chunks(plan)))
    liftoff, touchdown = shown.ground_steps
    times = np.linspace(0.0, plan.scenario.horizon, 2001)
    expected = plan.sample(times).position
    for n, drone in enumerate(show["swarm"]["drones"]):
        trajectory = drone["settings"]["trajectory"]
        assert trajectory["takeoffTime"] == pytest.approx(liftoff[n] * plan.scenario.dt)
        assert trajectory["points"][0][1][2] == 0.0 and trajectory["landingHeight"] == 0.0
        assert trajectory["points"][-1][0] == pytest.approx(
            (touchdown[n] - liftoff[n]) * plan.scenario.dt)
        assert drone["settings"]["home"] == pytest.approx(plan.scenario.starts[n].tolist())
        # before lift-off a player holds the first keyframe (the home), after touchdown the
        # last (the slot): the whole show is the plan's motion
        got = evaluate(trajectory, times)
        assert np.linalg.norm(got - expected[n], axis=1).max() < 0.01
    cues = [c["name"] for c in show["settings"]["cues"]["items"]]
    assert cues[0] == "takeoff" and cues[-1] == "landing"
    assert cues[1:-1] == ["grid", "sphere", "grid"]


@pytest.mark.parametrize(("change", "field", "words"), [
    ({"takeoff": {"grid": {**GRID, "rows": 2}}}, "takeoff.grid", "needs 9"),
    ({"takeoff": {"homes": [[0, 0]] * 8}}, "takeoff.homes", "needs 9"),
    ({"takeoff": {"homes": [[0, 0, 1]] * 9}}, "takeoff.homes[0]", "z = 0"),
    ({"takeoff": {"grid": GRID, "height": 30}}, "limits.position_max[2]", "lower"),
    ({"takeoff": {"grid": GRID}, "landing": {"homes": [[0, 0]] * 9,
                                             "assignment": "maybe"}},
     "landing.assignment", "'fixed' or 'free'"),
])
def test_bad_ground_legs_name_their_field(change: dict[str, Any], field: str,
                                          words: str) -> None:
    with pytest.raises(ScenarioError) as caught:
        parse_sequence(_show(**change))
    assert caught.value.field == field
    assert words in caught.value.reason


def test_a_landing_needs_a_takeoff_and_the_ground_in_the_box() -> None:
    data = _show()
    del data["takeoff"]
    data["landing"] = {}
    with pytest.raises(ScenarioError, match="needs a takeoff"):
        parse_sequence(data)
    data = _show()
    data["limits"]["position_min"][2] = 0.5
    with pytest.raises(ScenarioError, match=r"limits\.position_min\[2\]"):
        parse_sequence(data)


def test_a_show_in_the_air_is_unchanged() -> None:
    plain = parse_sequence(show_sequence(4, seed=1))
    assert plain.ground is None
    result: Plan = plan_sequence(plain).to_plan()
    assert result.sequence is not None and "ground" not in result.sequence


@pytest.mark.parametrize(("spacing", "count"), [((2.0, 2.0), 1), ((2.0, 0.8), 2),
                                                ((0.8, 0.8), 2), ((0.6, 0.6), 4)])
def test_waves_part_every_two_homes_closer_than_r(spacing: tuple[float, float],
                                                  count: int) -> None:
    from planner.methods.ground import WAVE_SLACK, waves

    homes = np.array([[c * spacing[0], r * spacing[1], 0.0] for r in range(6) for c in range(7)])
    wave = waves(homes, np.ones(3), 1.0)
    assert int(wave.max()) + 1 == count
    close = np.linalg.norm(homes[:, None] - homes[None], axis=2) < 1.0 * (1 + WAVE_SLACK)
    np.fill_diagonal(close, False)
    assert not (close & (wave[:, None] == wave[None])).any()


def test_a_landing_grid_with_spare_slots_takes_any_free_ones() -> None:
    """A tight 3 x 3 takeoff grid (four waves) and a 4 x 4 landing grid: nine different
    slots, each drone standing on its own at the end."""
    landing = {"origin": [-3.0, -3.0], "columns": 4, "rows": 4, "spacing": [0.6, 0.6]}
    data = _show(landing={"grid": landing})
    data["takeoff"] = {"grid": {"origin": [-1.0, -1.0], "columns": 3, "rows": 3,
                                "spacing": [0.6, 0.6]}}
    result = plan_sequence(data)
    assert result.ok, result.message
    ground = result.sequence.ground
    assert ground is not None and int(ground.takeoff_waves.max()) + 1 == 4
    assert len(set(ground.slot_index)) == 9 and max(ground.slot_index) < 16
    cells = np.array([[-3 + 0.6 * c, -3 + 0.6 * r, 0.0] for r in range(4) for c in range(4)])
    assert np.abs(result.positions[:, -1] - cells[list(ground.slot_index)]).max() < 1e-6
