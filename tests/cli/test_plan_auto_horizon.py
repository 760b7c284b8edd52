"""`fleetplan plan` with `steps: "auto"`: the summary gives the chosen horizon and the
candidates tried; a horizon that cannot exist under `max_horizon` is bad input (exit 2),
one the search could not find is a plan that did not verify (exit 1)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from gcs.cli.main import main
from planner.families.generators import circle_swap, show_sequence
from tests.paths import EXAMPLES


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(data))
    return path


def _flat(printed: str) -> str:
    return " ".join(printed.split())


@pytest.fixture(autouse=True)
def _wide(monkeypatch):
    """A terminal wide enough that the summary table wraps no cell."""
    monkeypatch.setenv("COLUMNS", "240")


def test_the_summary_gives_the_chosen_horizon(tmp_path, capsys):
    data = {**json.loads((EXAMPLES / "paper-circle4.json").read_text()), "steps": "auto"}
    out = tmp_path / "plan.json"
    assert main(["plan", str(_write(tmp_path, data)), "-o", str(out), "-q"]) == 0
    doc = json.loads(out.read_text())
    steps = doc["scenario"]["steps"]
    assert doc["horizon"]["chosen_steps"] == steps
    printed = _flat(capsys.readouterr().out)
    assert (f"horizon │ {steps * 0.2:g} s ({steps} steps of 0.2 s), chosen (steps tried: "
            f"{steps} converged)") in printed


def test_a_fixed_horizon_is_in_the_summary_too(tmp_path, capsys):
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "paper-circle2.json"), "-o", str(out), "-q"]) == 0
    assert "horizon │ 30 s (150 steps of 0.2 s) │" in _flat(capsys.readouterr().out)


def test_max_horizon_under_the_kinematic_bound_exits_2(tmp_path, capsys):
    data = {**json.loads((EXAMPLES / "paper-circle4.json").read_text()), "steps": "auto",
            "max_horizon": 1.0}
    out = tmp_path / "plan.json"
    assert main(["plan", str(_write(tmp_path, data)), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "error: max_horizon: 1 s (5 steps of dt) is too short" in err
    assert "Traceback" not in err and not out.exists()


def test_no_horizon_found_exits_1_and_says_so(tmp_path, capsys):
    # the crowded circle fails at 20 steps (10 % over its bound), where max_horizon ends it
    data = {**circle_swap(12, height_step=0.0, rotation=0.0, radius=2.5), "steps": "auto",
            "max_horizon": 4.0}
    out = tmp_path / "plan.json"
    assert main(["plan", str(_write(tmp_path, data)), "-o", str(out), "-q"]) == 1
    captured = capsys.readouterr()
    assert "no horizon up to max_horizon 4 s" in captured.err
    assert "none verified up to max_horizon 4 s" in _flat(captured.out)
    assert json.loads(out.read_text())["horizon"]["chosen_steps"] is None


def test_a_sequence_leg_line_says_its_steps_were_chosen(tmp_path, capsys):
    data = show_sequence(9, seed=2, hold=1.0)
    data["formations"][2]["duration"] = "auto"
    out = tmp_path / "show.plan.json"
    assert main(["plan", str(_write(tmp_path, data)), "-o", str(out)]) == 0
    legs = [line for line in capsys.readouterr().out.splitlines() if line.startswith("leg ")]
    assert len(legs) == 2
    assert "(chosen)" not in legs[0] and "150 steps" in legs[0]
    assert "steps (chosen)" in legs[1]
    chosen = json.loads(out.read_text())["sequence"]["legs"][1]["horizon"]["chosen_steps"]
    assert f"{chosen} steps (chosen)" in legs[1]
