"""Planning on an existing Dask cluster: real `dask scheduler` and `dask worker` processes,
used by `fleetplan plan --scheduler` and by the service (setting `scheduler`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from distributed import Client
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import EXAMPLES, example, free_port
from tests.paths import ROOT
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(300)



@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory: pytest.TempPathFactory
                 ) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """A scheduler and two single-thread workers, each its own `dask` process, shared by the
    module's tests (each only plans on it; none stops a worker)."""
    tmp_path = tmp_path_factory.mktemp("dask")
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    log = (tmp_path / "dask.log").open("wb")
    dask = [sys.executable, "-m", "dask"]
    processes = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port",
                                   str(port), "--no-dashboard"],
                                  env=env, cwd=tmp_path, stdout=log, stderr=log)]
    for _ in range(2):
        processes.append(subprocess.Popen(
            [*dask, "worker", address, "--nthreads", "1", "--no-dashboard",
             "--host", "127.0.0.1"], env=env, cwd=tmp_path, stdout=log, stderr=log))
    try:
        def both_workers() -> bool:
            try:
                with Client(address, timeout=5) as client:
                    return len(client.scheduler_info()["workers"]) == 2
            except OSError:
                return False

        wait_for(both_workers, "the scheduler and both workers", timeout=90.0, poll=0.1,
                 detail=lambda: (tmp_path / "dask.log").read_text(errors="replace"))
        yield address, processes
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(5)


def cluster_workers(address: str) -> set[str]:
    with Client(address, timeout=10) as client:
        return set(client.scheduler_info()["workers"])


def test_cli_plans_on_the_cluster(dask_cluster, tmp_path: Path) -> None:
    address, _ = dask_cluster
    out = tmp_path / "plan.json"
    result = subprocess.run(
        [sys.executable, "-m", "gcs.cli.main", "plan", str(EXAMPLES / "paper-circle4.json"),
         "-o", str(out), "--scheduler", address],
        cwd=tmp_path, capture_output=True, text=True, timeout=180,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert result.returncode == 0, result.stdout + result.stderr
    worker = result.stdout.split("planning on Dask worker ", 1)[1].split()[0]
    assert worker in cluster_workers(address)
    assert "iteration  0: cost" in result.stdout and "iteration  1: cost" in result.stdout
    plan = json.loads(out.read_text())
    assert plan["status"] == "converged" and len(plan["vehicles"]) == 4
    # Every iteration of the plan was printed as it came, labelled with its method (a busy
    # worker may print a losing attempt's iterations too: `auto` races when its head start
    # runs out).
    printed = [line for line in result.stdout.splitlines() if line.startswith("iteration ")]
    for it in plan["iterations"]:
        assert any(line.startswith(f"iteration {it['iteration']:2d}: cost {it['cost']:.4f}")
                   and line.endswith(f"[{it['method']}]") for line in printed), it


def test_cli_reports_an_unreachable_scheduler(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "gcs.cli.main", "plan", str(EXAMPLES / "paper-circle2.json"),
         "-o", str(tmp_path / "p.json"), "--scheduler", f"tcp://127.0.0.1:{free_port()}"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.startswith("error: cannot reach the Dask scheduler at tcp://")
    assert "Traceback" not in result.stderr


def test_service_plans_on_the_cluster(dask_cluster,
                                      make_settings: Callable[..., Settings]) -> None:
    address, _ = dask_cluster
    with TestClient(create_app(make_settings(scheduler=address))) as client:
        response = client.post("/api/missions?wait=120", json=example("paper-circle4"))
        assert response.status_code == 201, response.text
        mission = response.json()
        assert mission["status"] == "planned" and mission["plan"]["status"] == "converged"
        job = client.app.state.planning.job(mission["id"])
        assert job.worker in cluster_workers(address)
        # auto races two methods: the progress shows both, the plan the winner's iterations
        won = mission["plan"]["method"]
        assert [r["iteration"] for r in job.progress if r["method"] == won] == \
            [r["iteration"] for r in mission["plan"]["iterations"]]
    # The service only used the cluster: closing it left both workers running.
    assert len(cluster_workers(address)) == 2
