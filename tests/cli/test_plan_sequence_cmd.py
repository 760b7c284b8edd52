"""`fleetplan plan SEQUENCE.json`: the stitched plan (flyable), the per-vehicle CSVs, and
field-named errors with the scenario exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gcs.cli.main import main
from planner import Plan
from planner.families.generators import show_sequence
from planner.verification.verify import verify


@pytest.fixture(scope="module")
def sequence() -> dict:
    return show_sequence(6, seed=3, hold=1.0)


def test_plans_a_sequence_writes_a_flyable_plan_and_csvs(tmp_path, capsys, sequence):
    path = tmp_path / "show.json"
    path.write_text(json.dumps(sequence))
    out, csv_dir = tmp_path / "plan.json", tmp_path / "csv"
    code = main(["plan", str(path), "-o", str(out), "--csv-dir", str(csv_dir),
                 "--csv-rate", "4"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "planning 2 legs of 6 vehicles" in printed and "grid -> sphere" in printed
    plan = Plan.from_dict(json.loads(out.read_text()))
    assert plan.ok and plan.sequence is not None
    assert plan.scenario.horizon == pytest.approx(3 * 1.0 + 2 * 30.0)
    assert verify(plan.scenario, plan.positions(), plan.velocities(),
                  plan.accelerations()).verified
    files = sorted(p.name for p in csv_dir.iterdir())
    assert files == sorted(f"{vid}.csv" for vid in sequence["vehicles"])
    rows = (csv_dir / "uav1.csv").read_text().splitlines()
    assert rows[0] == "Time [msec],x [m],y [m],z [m]"
    assert len(rows) == 1 + 4 * 63 + 1  # 4 Hz over 63 s, both ends
    first, last = rows[1].split(","), rows[-1].split(",")
    assert first[0] == "0" and last[0] == "63000"
    n = plan.scenario.ids.index("uav1")
    np.testing.assert_allclose([float(x) for x in last[1:]], plan.positions()[n, -1], atol=1e-4)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d["formations"][1].pop("duration"), "formations[1].duration: is required"),
        (lambda d: d["formations"][2].update(duration=1.0),
         "formations[2].duration: too short"),
        (lambda d: d["formations"][1].update(colour="red"), "formations[1].colour: unknown key"),
        (lambda d: d.update(vehicles=["a"] * 6), "vehicles: ids must be unique"),
    ],
)
def test_bad_sequences_exit_2_naming_the_field(tmp_path, capsys, sequence, change, message):
    data = json.loads(json.dumps(sequence))
    change(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    assert main(["plan", str(path), "-o", str(tmp_path / "p.json"), "-q"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "p.json").exists()


def test_unsafe_ids_and_rates_are_refused_before_planning(tmp_path, capsys, sequence):
    data = json.loads(json.dumps(sequence))
    data["vehicles"][0] = "../escape"
    path = tmp_path / "s.json"
    path.write_text(json.dumps(data))
    assert main(["plan", str(path), "-o", str(tmp_path / "p.json"),
                 "--csv-dir", str(tmp_path / "csv")]) == 2
    assert "'../escape' cannot name a CSV file" in capsys.readouterr().err
    assert not (tmp_path / "p.json").exists() and not (tmp_path / "csv").exists()
    path.write_text(json.dumps(sequence))
    assert main(["plan", str(path), "-o", str(tmp_path / "p.json"),
                 "--csv-dir", str(tmp_path / "csv"), "--csv-rate", "nan"]) == 2
    assert "--csv-rate" in capsys.readouterr().err


def test_sequence_legs_run_on_a_dask_cluster_with_scheduler(tmp_path, capsys, sequence):
    from distributed import Client, LocalCluster

    path = tmp_path / "show.json"
    path.write_text(json.dumps(sequence))
    out = tmp_path / "plan.json"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      scheduler_port=0, dashboard_address=None) as cluster:
        code = main(["plan", str(path), "-o", str(out), "--scheduler",
                     cluster.scheduler_address])
        with Client(cluster.scheduler_address) as client:
            keys = client.run_on_scheduler(
                lambda dask_scheduler: [str(t[0]) for t in dask_scheduler.transition_log])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert f"on Dask at {cluster.scheduler_address}" in printed
    assert Plan.from_dict(json.loads(out.read_text())).ok
    # Both legs ran as tasks of this cluster (plan_leg-<hash> keys in the scheduler's log).
    assert len({k for k in keys if "plan_leg" in k}) == 2, sorted(set(keys))
