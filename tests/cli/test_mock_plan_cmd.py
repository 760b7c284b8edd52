"""`fleetplan mock --plan` with a plan it cannot use: exit 2 with the field named, never a
traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs.cli.main import main
from tests.flight.support import short_line, smooth_plan


def test_a_plan_whose_vehicles_do_not_match_its_scenario_is_named(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    document = smooth_plan(short_line(2)).to_dict()
    document["vehicles"] = document["vehicles"][:1]  # its scenario still has two
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(document))
    assert main(["mock", "--plan", str(path), "--duration", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: cannot use plan {path}: vehicles")
    assert "Traceback" not in err


def test_a_scenario_or_a_missing_file_is_refused(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "scenario.json"
    scenario.write_text(json.dumps(short_line(2)))
    assert main(["mock", "--plan", str(scenario), "--duration", "0"]) == 2
    assert "is a scenario, not a plan: plan it first" in capsys.readouterr().err
    assert main(["mock", "--plan", str(tmp_path / "none.json"), "--duration", "0"]) == 2
    assert "cannot use plan" in capsys.readouterr().err
