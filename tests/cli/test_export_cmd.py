"""`fleetplan export`: writes a .skyc that reads back as the plan, refuses what `fly` would
refuse, and says clearly what is wrong with its input or output (exit 2, no traceback, no
file left behind)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs.cli.main import main
from planner import Plan, Scenario
from planner import plan as make_plan
from tests.export.reader import evaluate, read_show
from tests.paths import EXAMPLES


@pytest.fixture(scope="module")
def plan_doc() -> dict[str, Any]:
    scenario = Scenario.from_dict(json.loads((EXAMPLES / "paper-circle2.json").read_text()))
    plan = make_plan(scenario)
    assert plan.ok, plan.problems()
    return plan.to_dict()


def _write(tmp_path: Path, document: Any, name: str = "plan.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(document))
    return path


def _leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.suffix in (".part", ".skyc"))


def test_exports_a_plan_that_reads_back_as_the_plan(tmp_path: Path, plan_doc) -> None:
    path = _write(tmp_path, plan_doc)
    out = tmp_path / "show.skyc"
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", "export", str(path),
                           "--format", "skyc", "-o", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert f"{out}: Skybrush compiled show, 2 drones, 30 s" in proc.stdout
    assert "x east, y north, z up" in proc.stdout
    plan = Plan.from_dict(plan_doc)
    show = read_show(out.read_bytes())
    times = np.linspace(0.0, plan.scenario.horizon, 601)
    expected = plan.sample(times).position
    for n, drone in enumerate(show["swarm"]["drones"]):
        assert drone["settings"]["name"] == plan.scenario.ids[n]
        got = evaluate(drone["settings"]["trajectory"], times)
        assert np.max(np.linalg.norm(got - expected[n], axis=1)) <= 0.01
    assert _leftovers(tmp_path) == ["show.skyc"]


def test_title_and_origin_go_into_the_show(tmp_path: Path, plan_doc, capsys) -> None:
    out = tmp_path / "show.skyc"
    assert main(["export", str(_write(tmp_path, plan_doc)), "-o", str(out), "--title",
                 "Opening", "--origin", "47.5,19.05,110"]) == 0
    assert "origin 47.5000000, 19.0500000" in capsys.readouterr().out
    show = read_show(out.read_bytes())
    assert show["meta"]["title"] == "Opening"
    assert show["environment"]["location"]["origin"] == [475000000, 190500000, 110000]


def test_a_scenario_is_refused_with_what_to_do(tmp_path: Path, capsys) -> None:
    scenario = EXAMPLES / "paper-circle2.json"
    assert main(["export", str(scenario), "-o", str(tmp_path / "show.skyc")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: {scenario} is a scenario, not a plan: plan it first (fleetplan plan "
        f"{scenario} -o PLAN.json), then export PLAN.json")
    assert _leftovers(tmp_path) == []


def test_a_plan_that_did_not_converge_is_refused_with_exit_1(tmp_path: Path, plan_doc,
                                                             capsys) -> None:
    stopped = {**plan_doc, "status": "max_iterations", "message": "stopped after 30"}
    assert main(["export", str(_write(tmp_path, stopped)), "-o",
                 str(tmp_path / "show.skyc")]) == 1
    assert capsys.readouterr().err.strip() == ("error: refusing to export the plan: its "
                                               "status is 'max_iterations': stopped after 30")
    assert _leftovers(tmp_path) == []


def test_a_plan_whose_claim_is_false_is_verified_again_and_refused(tmp_path: Path, plan_doc,
                                                                   capsys) -> None:
    """The file says converged and verified, but its second vehicle was edited onto the
    first's path: `export`, like `fly`, checks the trajectories themselves."""
    edited = json.loads(json.dumps(plan_doc))
    first, second = edited["vehicles"]
    second["position"] = [[x + 0.1, y, z] for x, y, z in first["position"]]
    assert main(["export", str(_write(tmp_path, edited)), "-o",
                 str(tmp_path / "show.skyc")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: refusing to export the plan: it fails verification: ")
    assert "separation" in err and "Traceback" not in err
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "error: cannot use plan"),
        ('{"status": "converged"}', "scenario: is required"),
    ],
)
def test_bad_plan_files_exit_2_naming_the_problem(tmp_path: Path, capsys, content: str,
                                                  message: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(content)
    assert main(["export", str(path), "-o", str(tmp_path / "show.skyc")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert main(["export", str(tmp_path / "missing.json"), "-o",
                 str(tmp_path / "show.skyc")]) == 2
    assert "No such file" in capsys.readouterr().err


def test_a_step_skybrush_cannot_time_exits_2_naming_dt(tmp_path: Path, capsys) -> None:
    scenario = json.loads((EXAMPLES / "paper-circle2.json").read_text())
    scenario["dt"], scenario["steps"] = 0.0125, 2400
    plan = make_plan(Scenario.from_dict(scenario))
    path = _write(tmp_path, plan.to_dict())
    assert main(["export", str(path), "-o", str(tmp_path / "show.skyc")]) == 2
    assert "error: scenario.dt: 0.0125 s is not a whole number of milliseconds" in \
        capsys.readouterr().err
    assert _leftovers(tmp_path) == []


def test_an_output_that_cannot_be_written_exits_2(tmp_path: Path, plan_doc, capsys) -> None:
    path = _write(tmp_path, plan_doc)
    missing = tmp_path / "no" / "such" / "dir" / "show.skyc"
    assert main(["export", str(path), "-o", str(missing)]) == 2
    assert capsys.readouterr().err.strip() == (f"error: cannot write {missing}: No such file "
                                               f"or directory")
    assert main(["export", str(path), "-o", str(tmp_path)]) == 2  # a directory
    assert f"error: cannot write {tmp_path}: " in capsys.readouterr().err
    assert _leftovers(tmp_path) == []


def test_bad_options_exit_2(tmp_path: Path, plan_doc, capsys) -> None:
    path = _write(tmp_path, plan_doc)
    assert main(["export", str(path), "-o", str(tmp_path / "s.skyc"), "--origin", "91,0"]) == 2
    assert "error: origin: latitude must be between -90 and 90, got 91" in \
        capsys.readouterr().err
    with pytest.raises(SystemExit) as caught:
        main(["export", str(path), "-o", str(tmp_path / "s.skyc"), "--format", "kml"])
    assert caught.value.code == 2
    assert "invalid choice: 'kml'" in capsys.readouterr().err
    assert _leftovers(tmp_path) == []
