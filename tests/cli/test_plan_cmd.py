"""`fleetplan plan`: exit status, progress lines, summary and clear errors."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from gcs.cli.main import main
from tests.paths import EXAMPLES


def test_plans_an_example_and_writes_the_plan(tmp_path, capsys):
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "paper-circle4.json"), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "iteration  0: cost" in printed and "iteration  1: cost" in printed
    assert "converged" in printed and "plan written to" in printed
    doc = json.loads(out.read_text())
    assert doc["status"] == "converged"
    assert len(doc["vehicles"]) == 4
    assert "obstacle clearance" not in printed  # no obstacles, no row


def test_the_summary_gives_the_clearance_kept_from_the_obstacles(tmp_path, capsys):
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "pillar-circle8.json"), "-o", str(out), "-q"]) == 0
    printed = " ".join(capsys.readouterr().out.split())  # the table may wrap a cell
    verification = json.loads(out.read_text())["verification"]
    kept = verification["obstacle_distance_min"]
    assert kept >= 0.5 - 1e-4 and verification["closest_obstacle"]["id"] == "pillar"
    assert f"obstacle clearance (continuous) │ {kept:.4f} m (clearance 0.5 m)" in printed
    assert "'pillar'" in printed


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "is not valid JSON"),
        ('{"dt": 0.2}', "steps: is required"),
        ('{"dt": 0.2, "steps": 10, "min_separation": 1, "limits": {}, "vehicles": []}',
         "limits.position_min: is required"),
    ],
)
def test_bad_input_exits_2_with_a_message(tmp_path, capsys, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    assert main(["plan", str(path), "-o", str(tmp_path / "p.json")]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err
    assert not (tmp_path / "p.json").exists()


def test_missing_file(tmp_path, capsys):
    assert main(["plan", str(tmp_path / "nope.json")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_infeasible_plan_exits_1_and_still_writes(tmp_path, capsys):
    data = json.loads((EXAMPLES / "paper-circle4.json").read_text())
    data["steps"] = 40
    data["limits"]["jerk_max"] = [0.05, 0.05, 0.05]
    path = tmp_path / "tight.json"
    path.write_text(json.dumps(data))
    out = tmp_path / "p.json"
    assert main(["plan", str(path), "-o", str(out), "-q"]) == 1
    captured = capsys.readouterr()
    assert "infeasible" in captured.err
    assert json.loads(out.read_text())["status"] == "infeasible"
    # an infeasible plan has no cost: the table says so with "-", never "nan" or "None"
    assert "nan" not in captured.out.lower() and "None" not in captured.out


def test_console_script_is_installed(tmp_path):
    out = tmp_path / "plan.json"
    done = subprocess.run(
        [str(Path(sys.executable).parent / "fleetplan"), "plan",
         str(EXAMPLES / "paper-random2.json"), "-o", str(out), "-q"],
        capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert out.exists()


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    printed = capsys.readouterr().out.split()
    assert printed[0] == "fleetplan"
    assert printed[1][0].isdigit()  # the installed package's version, e.g. 0.1.0


def _table_row(printed: str, label: str) -> str:
    """The value column of the summary-table row `label` (rich box or plain text)."""
    for line in printed.splitlines():
        cells = [c.strip() for c in line.replace("│", "|").split("|") if c.strip()]
        if cells and cells[0] == label:
            return " ".join(cells[1:])
    raise AssertionError(f"no row {label!r} in:\n{printed}")


def test_the_table_and_the_exit_verdict_are_one_verification(tmp_path, capsys):
    """max_iterations 1 stops an 8-vehicle circle before it converges: its checks pass, but
    the plan is not verified, and the table says the same as the error line. (The whole
    fleet: batches of one vehicle converge in one iteration.)"""
    data = json.loads((EXAMPLES / "paper-circle8.json").read_text())
    data["max_iterations"] = 1
    data["method"] = "whole"
    path = tmp_path / "short.json"
    path.write_text(json.dumps(data))
    assert main(["plan", str(path), "-o", str(tmp_path / "p.json"), "-q"]) == 1
    captured = capsys.readouterr()
    verified = _table_row(captured.out, "verified")
    assert verified.startswith("NO") and "max_iterations" in verified
    assert "error: plan not verified: status max_iterations" in captured.err
    assert _table_row(captured.out, "checks") == "pass"


def test_a_converged_plan_reads_verified_in_both(tmp_path, capsys):
    assert main(["plan", str(EXAMPLES / "paper-circle2.json"), "-o",
                 str(tmp_path / "p.json"), "-q"]) == 0
    captured = capsys.readouterr()
    assert _table_row(captured.out, "verified") == "yes"
    assert "error" not in captured.err


def test_a_scale_that_would_overflow_the_metric_is_bad_input(tmp_path, capsys):
    data = json.loads((EXAMPLES / "paper-circle4.json").read_text())
    data["separation_scale"] = [1e-300, 1e-300, 1e-300]
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(data))
    assert main(["plan", str(path), "-o", str(tmp_path / "p.json"), "-q"]) == 2
    assert "separation_scale[0]: must be between 0.1 and 10" in capsys.readouterr().err
    assert not (tmp_path / "p.json").exists()


def test_prioritized_batches_plan_a_crowd_and_the_plan_says_so(tmp_path, capsys):
    from planner.families.generators import sideways

    scenario = tmp_path / "sideways.json"
    scenario.write_text(json.dumps(sideways(16)))
    out = tmp_path / "plan.json"
    assert main(["plan", str(scenario), "-o", str(out), "-q", "--decompose", "prioritized",
                 "--batch-size", "4"]) == 0
    doc = json.loads(out.read_text())
    check = doc["verification"]
    assert doc["status"] == "converged" and check["separated"] and check["within_bounds"]
    assert check["min_separation_continuous"] >= 1.0 - check["separation_tolerance"]
    assert "prioritized batches of up to 4 vehicles" in doc["message"]
    assert "whole fleet" not in doc["message"]
    assert doc["method"] == "prioritized" and doc["scenario"]["method"] == "prioritized"
    assert re.search(r"verified\s+.\s+yes", capsys.readouterr().out)


@pytest.mark.parametrize(("flags", "method"), [
    (["--method", "whole"], "whole"), (["--decompose", "none"], "whole"),
    (["--method", "prioritized"], "prioritized"), (["--decompose", "prioritized"], "prioritized"),
])
def test_the_method_flags_choose_the_method_and_the_summary_and_lines_name_it(
        tmp_path, capsys, flags, method):
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "paper-circle4.json"), "-o", str(out), *flags]) == 0
    printed = capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert doc["method"] == method and doc["scenario"]["method"] == method
    assert {a["method"]: a["outcome"] for a in doc["attempts"]}[method] == "won"
    assert re.search(rf"method\s+.\s+{method}", printed)
    lines = [line for line in printed.splitlines() if line.startswith("iteration")]
    assert lines and all(re.search(rf"\[{method}( batch \d+/\d+)?\]$", line) for line in lines)


def test_the_default_method_is_the_scenarios_then_auto(tmp_path, capsys):
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "paper-circle4.json"), "-o", str(out), "-q"]) == 0
    doc = json.loads(out.read_text())
    assert doc["scenario"]["method"] == "auto"
    assert doc["method"] in ("whole", "prioritized") and doc["attempts"]
    data = json.loads((EXAMPLES / "paper-circle4.json").read_text()) | {"method": "prioritized"}
    scenario = tmp_path / "batches.json"
    scenario.write_text(json.dumps(data))
    assert main(["plan", str(scenario), "-o", str(out), "-q"]) == 0
    assert json.loads(out.read_text())["method"] == "prioritized"


@pytest.mark.parametrize(("flags", "message"), [
    (["--decompose", "fancy"], "--decompose: must be one of none, prioritized, got 'fancy'"),
    (["--method", "fancy"], "--method: must be one of auto, whole, prioritized, got 'fancy'"),
    (["--method", "whole", "--decompose", "prioritized"],
     "--decompose prioritized asks for method prioritized, --method for whole"),
    (["--decompose", "prioritized", "--batch-size", "0"], "--batch-size: must be a whole"),
    (["--method", "whole", "--batch-size", "4"],
     "--batch-size: applies with --method auto or prioritized"),
    (["--decompose", "none", "--batch-size", "4"],
     "--batch-size: applies with --method auto or prioritized"),
])
def test_bad_decomposition_flags_exit_2_naming_the_flag(tmp_path, capsys, flags, message):
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "paper-circle4.json"), "-o", str(out), *flags]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_sequence_refuses_the_decomposition_flags(tmp_path, capsys):
    sequence = tmp_path / "show.json"
    sequence.write_text(json.dumps({"formations": []}))
    assert main(["plan", str(sequence), "--decompose", "prioritized"]) == 2
    assert "--method, --decompose, --batch-size: apply to a scenario" in capsys.readouterr().err
    assert main(["plan", str(sequence), "--method", "whole"]) == 2


def test_auto_labels_each_iteration_line_with_its_method_and_names_the_winner(
        tmp_path, capsys):
    """With obstacles auto races both methods at once: every iteration line says which
    method computed it, and the summary names the one that planned."""
    out = tmp_path / "plan.json"
    assert main(["plan", str(EXAMPLES / "pillar-circle8.json"), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    lines = [line for line in printed.splitlines() if line.startswith("iteration")]
    assert lines and all(re.search(r"\[(whole|prioritized( batch \d+/\d+)?)\]$", line)
                         for line in lines)
    doc = json.loads(out.read_text())
    assert doc["method"] in ("whole", "prioritized")
    outcomes = {a["method"]: a["outcome"] for a in doc["attempts"]}
    assert outcomes[doc["method"]] == "won"
    assert re.search(rf"method\s+.\s+{doc['method']}", printed)


def test_long_iterations_print_the_groups_solved_so_far(tmp_path, capsys, monkeypatch):
    """Inside an iteration a line per report (`planner.IterationProgress`: every group with
    the report interval at zero), before the iteration's own line."""
    from planner.scp import loop

    monkeypatch.setattr(loop, "PROGRESS_EVERY_S", 0.0)
    assert main(["plan", str(EXAMPLES / "random16.json"), "-o", str(tmp_path / "p.json"),
                 "--method", "whole"]) == 0
    lines = capsys.readouterr().out.splitlines()
    inside = [n for n, line in enumerate(lines) if line.startswith("  ... iteration  1:")]
    assert inside, lines
    assert re.fullmatch(r"  \.\.\. iteration  1: round \d+, \d+/\d+ groups solved \(largest "
                        r"\d+ vehicles, rows \d+\), QPs \d+, [0-9.]+ s  \[whole\]",
                        lines[inside[0]])
    record = next(n for n, line in enumerate(lines) if line.startswith("iteration  1:"))
    assert max(inside) < record
