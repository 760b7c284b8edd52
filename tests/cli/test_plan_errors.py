"""`fleetplan plan`'s errors say the fix: a plan given as a scenario is named as a plan with
the commands that take one, a mistyped key gets the nearest known key, every problem of shape
is listed (as the REST API lists them), vehicles are named by id, and batch planning says
which batch each iteration line belongs to and sums up the whole plan's cost."""

from __future__ import annotations

import json
import re

import numpy as np

from gcs.cli.main import main
from gcs.cli.scenario_check import MAX_LISTED
from planner.scp.loop import thrust_cost
from tests.paths import EXAMPLES


def _scenario(tmp_path, change):
    data = json.loads((EXAMPLES / "paper-circle4.json").read_text())
    change(data)
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(data))
    return path


def _errors(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]


def test_a_plan_given_to_plan_is_named_as_a_plan_with_the_commands_that_take_it(
        tmp_path, capsys):
    plan = tmp_path / "made.plan.json"
    assert main(["plan", str(EXAMPLES / "paper-circle2.json"), "-o", str(plan), "-q"]) == 0
    capsys.readouterr()
    assert main(["plan", str(plan), "-o", str(tmp_path / "again.json")]) == 2
    (line,) = _errors(capsys)
    assert f"{plan} is a plan, not a scenario" in line
    assert f"fleetplan fly {plan} --mock" in line and f"fleetplan export {plan}" in line
    assert "unknown key" not in line
    assert not (tmp_path / "again.json").exists()


def test_a_mistyped_key_gets_the_nearest_key_of_the_contract(tmp_path, capsys):
    def typo(data):
        data["min_seperation"] = data.pop("min_separation")
        data["limits"]["velocity_maxx"] = data["limits"].pop("velocity_max")

    assert main(["plan", str(_scenario(tmp_path, typo))]) == 2
    errors = _errors(capsys)
    assert "error: min_seperation: unknown key (did you mean 'min_separation'?)" in errors
    assert ("error: limits.velocity_maxx: unknown key (did you mean 'velocity_max'?)"
            in errors)
    assert "error: min_separation: is required" in errors


def test_a_key_like_none_of_the_contract_gets_no_guess(tmp_path, capsys):
    assert main(["plan", str(_scenario(tmp_path, lambda d: d.update(colour="red")))]) == 2
    assert _errors(capsys) == ["error: colour: unknown key"]


def test_every_problem_of_shape_is_listed_each_vehicle_by_its_id(tmp_path, capsys):
    def broken(data):
        data["dt"] = "fast"
        data["vehicles"][1]["goal"] = [1.0, 2.0]
        data["vehicles"][3]["start"] = "home"

    assert main(["plan", str(_scenario(tmp_path, broken))]) == 2
    ids = [v["id"] for v in json.loads((EXAMPLES / "paper-circle4.json").read_text())
           ["vehicles"]]
    errors = _errors(capsys)
    assert errors == [
        "error: dt: must be a number, got string",
        f"error: vehicles[1].goal (vehicle '{ids[1]}'): must be a list of 3 numbers [x, y, z]",
        f"error: vehicles[3].start (vehicle '{ids[3]}'): must be a list of 3 numbers [x, y, z]",
    ]


def test_every_problem_of_the_settings_is_listed(tmp_path, capsys):
    """Problems of meaning in several settings are told at once, in the document's order;
    one alone is told on its own."""
    def wrong(data):
        data["dt"] = -1
        data["min_separation"] = 0
        data["method"] = "fastest"

    assert main(["plan", str(_scenario(tmp_path, wrong))]) == 2
    assert _errors(capsys) == [
        "error: dt: must be positive, got -1",
        "error: min_separation: must be positive, got 0",
        "error: method: must be one of 'auto', 'whole', 'prioritized', got 'fastest'",
    ]
    assert main(["plan", str(_scenario(tmp_path, lambda d: d.update(steps=2)))]) == 2
    (line,) = _errors(capsys)
    assert line == "error: steps: must be between 3 and 5000, got 2"


def test_a_problem_of_meaning_names_the_vehicle_by_id(tmp_path, capsys):
    def outside(data):
        data["vehicles"][2]["goal"] = [99.0, 1.0, 1.0]

    assert main(["plan", str(_scenario(tmp_path, outside))]) == 2
    (line,) = _errors(capsys)
    assert line.startswith("error: vehicles[2].goal (vehicle 'uav3'): ")
    assert "workspace" in line


def test_a_file_with_many_problems_lists_a_capped_number_and_counts_the_rest(
        tmp_path, capsys):
    def many(data):
        vehicle = data["vehicles"][0]
        data["vehicles"] = [{**vehicle, "id": f"v{n}", "goal": "x"} for n in range(30)]

    assert main(["plan", str(_scenario(tmp_path, many))]) == 2
    errors = _errors(capsys)
    assert len(errors) == MAX_LISTED + 1
    assert errors[0] == ("error: vehicles[0].goal (vehicle 'v0'): must be a list of 3 numbers "
                         "[x, y, z]")
    assert errors[-1] == f"error: ... and {30 - MAX_LISTED} more problems"


def test_batch_lines_name_their_batch_and_the_summary_sums_the_whole_plan(tmp_path, capsys):
    from planner.families.generators import sideways

    scenario = tmp_path / "sideways.json"
    scenario.write_text(json.dumps(sideways(16)))
    out = tmp_path / "plan.json"
    assert main(["plan", str(scenario), "-o", str(out), "--method", "prioritized",
                 "--batch-size", "4"]) == 0
    printed = capsys.readouterr().out
    batches = [re.search(r"\[prioritized batch (\d+)/(\d+)\]$", line)
               for line in printed.splitlines() if line.startswith("iteration")]
    assert batches and all(batches)
    numbers = [int(m.group(1)) for m in batches if m]
    assert numbers[0] == 1 and numbers == sorted(numbers) and numbers[-1] == 4
    assert {int(m.group(2)) for m in batches if m} == {4}
    doc = json.loads(out.read_text())
    assert [r["batch"] for r in doc["iterations"]] == numbers
    whole = thrust_cost(np.array([v["acceleration"] for v in doc["vehicles"]]))
    last_batch = doc["iterations"][-1]["cost"]
    assert whole > 2 * last_batch  # four batches: the last one's cost is not the plan's
    summary = re.search(r"cost \(sum \|\|a\+g\|\|\^2\)\s+.\s+([0-9.]+)", printed)
    assert summary and float(summary.group(1)) == round(whole, 4)
