"""A show on the ground with lights through every command: plan, export, import, plan the
import again, report: the formations, colours, homes and slots survive the round trip."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gcs.cli.main import main
from tests.support.shows import ground_show as _show


def test_plan_export_import_plan_report(tmp_path: Path, capsys) -> None:
    design = _show(landing={})
    design["formations"][0]["color"] = "#ff0000"
    design["formations"][1]["color"] = [[0, 25 * n, 255 - 25 * n] for n in range(9)]
    (tmp_path / "show.json").write_text(json.dumps(design))
    files = {name: str(tmp_path / name) for name in
             ("show.json", "plan.json", "show.skyc", "back.json", "back.plan.json",
              "report.html")}
    assert main(["plan", files["show.json"], "-o", files["plan.json"]]) == 0
    assert main(["export", files["plan.json"], "-o", files["show.skyc"]]) == 0
    assert main(["import", files["show.skyc"], "-o", files["back.json"]]) == 0
    assert main(["plan", files["back.json"], "-o", files["back.plan.json"]]) == 0
    assert main(["report", files["back.plan.json"], "-o", files["report.html"]]) == 0
    capsys.readouterr()
    planned = json.loads(Path(files["plan.json"]).read_text())["sequence"]
    back = json.loads(Path(files["back.json"]).read_text())
    homes = planned["ground"]["takeoff"]["homes"]
    expected = [homes[vid][:2] for vid in back["vehicles"]]
    assert np.abs(np.array(back["takeoff"]["homes"]) - expected).max() < 1e-6
    # the sphere's colours come back drone by drone
    colors = planned["formations"][1]["colors"]
    assert back["formations"][1]["color"] == [colors[vid] for vid in back["vehicles"]]
    replanned = json.loads(Path(files["back.plan.json"]).read_text())["sequence"]
    assert replanned["timeline"][0]["kind"] == "takeoff"
    slots = np.array([replanned["ground"]["landing"]["slots"][v] for v in back["vehicles"]])
    assert np.abs(slots[:, 2]).max() == 0.0
