"""docker-compose.yml: the service plans on the compose file's own Dask cluster (a scheduler
and two workers from the fleetplan image), validated by `docker-compose config`."""

from __future__ import annotations

import shutil
import subprocess

import pytest
import yaml

from tests.paths import ROOT


def test_compose_has_a_dask_scheduler_and_two_workers_the_service_uses() -> None:
    if shutil.which("docker-compose") is None:
        pytest.skip("docker-compose is not installed (sudo apt-get install docker-compose)")
    result = subprocess.run(["docker-compose", "-f", "docker-compose.yml", "config"],
                            cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    services = yaml.safe_load(result.stdout)["services"]
    scheduler = services["dask-scheduler"]
    assert scheduler["entrypoint"] == ["dask", "scheduler"]
    assert "8786" in scheduler["command"]
    assert "ports" not in scheduler  # the Dask protocol is unauthenticated: network only
    workers = {name: s for name, s in services.items() if name.startswith("dask-worker")}
    assert len(workers) == 2
    for worker in workers.values():
        assert worker["entrypoint"] == ["dask", "worker"]
        assert worker["command"][0] == "tcp://dask-scheduler:8786"
        assert worker["image"] == services["fleetplan"]["image"]  # the planner inside
        assert "ports" not in worker
    service = services["fleetplan"]
    assert service["environment"]["FLEETPLAN_SCHEDULER"] == "tcp://dask-scheduler:8786"
    assert {"dask-scheduler", *workers} <= set(service["depends_on"])
