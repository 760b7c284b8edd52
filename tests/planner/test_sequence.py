"""Formation sequences: independent legs, stitching at rest, whole-timeline verification,
field-named validation, and the per-vehicle CSV export."""

from __future__ import annotations

import copy
import pickle
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import pytest

from planner import ScenarioError
from planner.families.generators import show_sequence
from planner.methods.sequence import (
    dynamics_residual,
    parse_sequence,
    plan_leg,
    plan_sequence,
    trajectory_csv,
)
from planner.model.dynamics import interpolate


@pytest.fixture(scope="module")
def small() -> dict[str, Any]:
    return show_sequence(9, seed=2, hold=1.0)


@pytest.fixture(scope="module")
def planned(small):
    return plan_sequence(small)


def test_sequence_plans_and_verifies_as_a_whole(small, planned):
    assert planned.status == "converged", planned.message
    seq = planned.sequence
    assert len(planned.legs) == 2 and all(leg.ok for leg in planned.legs)
    legs_steps = [leg.scenario.steps for leg in planned.legs]
    assert planned.accelerations.shape[1] == sum(seq.holds) + sum(legs_steps)
    assert planned.duration == pytest.approx(3 * 1.0 + 2 * 30.0)
    assert planned.verification.verified
    assert planned.verification.min_separation_continuous >= 1.0 - 1e-4
    assert planned.dynamics_error < 1e-9
    # The fleet ends where it started (grid -> sphere -> grid), each vehicle on a grid point.
    np.testing.assert_allclose(np.sort(planned.positions[:, -1], axis=0),
                               np.sort(planned.positions[:, 0], axis=0), atol=1e-9)
    assert seq.formation_names == ("grid", "sphere", "grid")
    assert planned.verification.closest_time <= planned.duration


def test_legs_are_stitched_at_rest_on_the_formations(planned):
    seq = planned.sequence
    holds = [s for s in planned.segments if s["kind"] == "hold"]
    assert len(holds) == len(seq.formation_names)  # every formation held (hold = 1 s)
    for f, segment in enumerate(holds):
        k0, k1 = round(segment["start_s"] / seq.dt), round(segment["end_s"] / seq.dt)
        np.testing.assert_allclose(planned.positions[:, k0:k1 + 1],
                                   np.repeat(seq.points[f][:, None], k1 - k0 + 1, 1), atol=1e-9)
        np.testing.assert_allclose(planned.velocities[:, k0:k1 + 1], 0.0, atol=1e-12)
        np.testing.assert_allclose(planned.accelerations[:, k0:k1], 0.0, atol=1e-12)
    for segment in planned.segments:
        if segment["kind"] == "leg":  # at rest at both ends, no acceleration at the end
            k0, k1 = round(segment["start_s"] / seq.dt), round(segment["end_s"] / seq.dt)
            np.testing.assert_allclose(planned.velocities[:, [k0, k1]], 0.0, atol=1e-6)
            np.testing.assert_allclose(planned.accelerations[:, k1 - 1], 0.0, atol=1e-6)
    # Each leg starts where the previous formation's assigned points are.
    for k, leg in enumerate(planned.legs):
        np.testing.assert_allclose(leg.positions()[:, 0], seq.points[k], atol=1e-9)
        np.testing.assert_allclose(leg.positions()[:, -1], seq.points[k + 1], atol=1e-6)


def test_legs_are_pure_and_picklable(small, planned):
    seq = parse_sequence(small)
    legs = pickle.loads(pickle.dumps(seq.legs))
    again = plan_leg(legs[1])
    np.testing.assert_array_equal(again.positions(), planned.legs[1].positions())
    with ThreadPoolExecutor(2) as pool:
        parallel = plan_sequence(seq, mapper=pool.map)
    np.testing.assert_array_equal(parallel.positions, planned.positions)
    assert parallel.status == "converged"


def test_free_formations_report_slots(planned, small):
    out = planned.to_dict()
    sphere = out["formations"][1]
    assert sorted(sphere["slots"].values()) == list(range(9))
    given = np.array(small["formations"][1]["positions"])
    arrived = planned.legs[0].positions()[:, -1]
    order = [sphere["slots"][vid] for vid in out["vehicles"]]
    np.testing.assert_allclose(arrived, given[order], atol=1e-6)
    assert [s["kind"] for s in out["timeline"]] == ["hold", "leg", "hold", "leg", "hold"]


def test_dynamics_residual_catches_a_broken_stitch(planned):
    p = planned.positions.copy()
    p[:, 200:] += 0.3  # a jump in the middle of the timeline
    assert dynamics_residual(p, planned.velocities, planned.accelerations, 0.2) > 0.29


def _broken(small: dict[str, Any], path: list[Any], value: Any) -> str:
    data = copy.deepcopy(small)
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    with pytest.raises(ScenarioError) as info:
        parse_sequence(data)
    return info.value.field


def test_sequence_errors_name_the_field(small):
    sphere = small["formations"][1]["positions"]
    assert _broken(small, ["formations", 1, "duration"], KeyError) == "formations[1].duration"
    assert _broken(small, ["formations", 1, "duration"], 0.6) == "formations[1].duration"
    assert _broken(small, ["formations", 1, "duration"], -3) == "formations[1].duration"
    assert _broken(small, ["formations", 1, "hold"], 0.33) == "formations[1].hold"
    assert _broken(small, ["formations", 0, "duration"], 5) == "formations[0].duration"
    assert _broken(small, ["formations", 2, "positions"], sphere[:3]) == "formations[2].positions"
    assert (_broken(small, ["formations", 1, "positions", 2], [1, "x", 2])
            == "formations[1].positions[2][1]")
    close = copy.deepcopy(sphere)
    close[4] = [close[3][0] + 0.1, close[3][1], close[3][2]]
    assert _broken(small, ["formations", 1, "positions"], close).startswith(
        "formations[1].positions[")
    assert _broken(small, ["formations", 1, "assignment"], "any") == "formations[1].assignment"
    assert _broken(small, ["formations", 1, "colour"], "red") == "formations[1].colour"
    assert _broken(small, ["formations"], small["formations"][:1]) == "formations"
    assert _broken(small, ["vehicles"], ["a"] * 9) == "vehicles"
    assert _broken(small, ["assignment"], "some") == "assignment"


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        (["dt"], 1e-300, "dt"),
        (["dt"], 10**400, "dt"),
        (["separation_scale"], [1e-300, 1e-300, 1e-300], "separation_scale[0]"),
        (["formations", 1, "duration"], 1e308, "formations[1].duration"),
        (["formations", 1, "hold"], 1e300, "formations[1].hold"),
        (["formations", 1, "positions", 0], [1e300, 0.0, 1.0], "formations[1].positions[0][0]"),
        (["formations", 1, "positions", 0], [10**400, 0.0, 1.0],
         "formations[1].positions[0][0]"),
        (["vehicles", 3], "uav\x004", "vehicles[3]"),
        (["vehicles", 0], "\x1b]0;owned\x07", "vehicles[0]"),
    ],
    ids=lambda x: "huge-int" if x == 10**400 else None,
)
def test_sequence_numbers_and_ids_outside_their_ranges_are_refused(small, path, value, field):
    """Checked before any assignment or step count is derived from them."""
    assert _broken(small, path, value) == field


def test_csv_has_one_file_per_vehicle_with_millisecond_times(planned):
    seq = planned.sequence
    at_steps = trajectory_csv(planned.positions, planned.velocities, planned.accelerations,
                              seq.dt, seq.ids)
    assert list(at_steps) == list(seq.ids)
    lines = at_steps[seq.ids[3]].splitlines()
    assert lines[0] == "Time [msec],x [m],y [m],z [m]"
    rows = np.array([[float(c) for c in line.split(",")] for line in lines[1:]])
    assert len(rows) == planned.positions.shape[1]
    assert all(line.split(",")[0].isdigit() for line in lines[1:])
    np.testing.assert_array_equal(rows[:3, 0], [0, 200, 400])
    assert rows[-1, 0] == round(planned.duration * 1000)
    np.testing.assert_allclose(rows[:, 1:], planned.positions[3], atol=5e-5)
    rated = trajectory_csv(planned.positions, planned.velocities, planned.accelerations,
                           seq.dt, seq.ids, rate_hz=25)[seq.ids[3]].splitlines()[1:]
    t = np.array([float(line.split(",")[0]) for line in rated]) / 1000
    xyz = np.array([[float(c) for c in line.split(",")[1:]] for line in rated])
    assert np.all(np.diff(t) == pytest.approx(0.04))
    exact = interpolate(planned.positions[3], planned.velocities[3], planned.accelerations[3],
                        seq.dt, t).position
    np.testing.assert_allclose(xyz, exact, atol=5e-5)
    with pytest.raises(ValueError):
        trajectory_csv(planned.positions, planned.velocities, planned.accelerations, seq.dt,
                       seq.ids, rate_hz=float("nan"))


def test_the_documented_example_sequence_plans():
    import json
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs/planning/sequences.md").read_text()
    block = re.search(r"# Formation sequences.*?```json\n(.*?)```", page, re.S)
    assert block is not None
    show = plan_sequence(json.loads(block.group(1)))
    assert show.status == "converged", show.message
    assert show.duration == pytest.approx(67.0)


def test_stitched_plan_is_flyable_verifies_and_round_trips(planned):
    import json

    from planner import Plan
    from planner.verification.verify import verify

    flyable = planned.to_plan()
    assert flyable.ok and flyable.status == "converged"
    seq = planned.sequence
    scenario = flyable.scenario
    assert scenario.assignment == "fixed"
    assert scenario.steps == planned.accelerations.shape[1]
    np.testing.assert_allclose(scenario.starts, seq.points[0])
    np.testing.assert_allclose(scenario.goals, seq.points[-1])
    # The executor's re-verification (verify on the plan's own scenario) accepts it.
    again = verify(scenario, flyable.positions(), flyable.velocities(), flyable.accelerations())
    assert again.verified
    text = json.dumps(flyable.to_dict(), allow_nan=False)
    back = Plan.from_dict(json.loads(text))
    assert back.ok and back.scenario.steps == scenario.steps
    np.testing.assert_allclose(back.positions(), planned.positions)
    assert back.sequence == flyable.sequence
    assert [f["name"] for f in back.sequence["formations"]] == list(seq.formation_names)
    assert [leg["status"] for leg in back.sequence["legs"]] == ["converged", "converged"]
    assert back.sequence["timeline"][0]["kind"] == "hold"


def test_plain_plan_json_has_a_null_sequence_block(planned):
    from planner import Plan

    leg = planned.legs[0].to_dict()
    assert leg["sequence"] is None
    assert Plan.from_dict(leg).sequence is None
    del leg["sequence"]  # plans written before the block existed still read
    assert Plan.from_dict(leg).sequence is None
    with pytest.raises(Exception, match="sequence"):
        Plan.from_dict({**leg, "sequence": [1, 2]})
