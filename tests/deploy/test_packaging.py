"""Deployment files: docker-compose.yml is valid and consistent with its fleet file, and the
wheel carries the browser page so an installed service (the Docker image) can serve it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import yaml

from tests.paths import ROOT


@pytest.fixture(scope="module")
def compose_config() -> dict:
    if shutil.which("docker-compose") is None:
        pytest.skip("docker-compose is not installed (sudo apt-get install docker-compose)")
    result = subprocess.run(
        ["docker-compose", "-f", "docker-compose.yml", "config"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )
    assert result.returncode == 0, result.stderr
    return yaml.safe_load(result.stdout)


def test_compose_file_is_valid(compose_config: dict) -> None:
    services = compose_config["services"]
    assert "fleetplan" in services
    assert services["fleetplan"]["build"]["context"] == str(ROOT)


def test_compose_vehicles_match_the_fleet_file(compose_config: dict) -> None:
    services = compose_config["services"]
    service = services["fleetplan"]
    # v1 prints short syntax: SOURCE:TARGET[:MODE]
    mounts = {v.split(":")[1]: v.split(":")[0] for v in service["volumes"]}
    fleet_path = Path(mounts["/etc/fleetplan/fleet.json"])
    assert fleet_path.is_file()
    assert service["command"] == ["--fleet", "/etc/fleetplan/fleet.json"]
    fleet = json.loads(fleet_path.read_text())
    sitl = {name: s for name, s in services.items() if name.startswith("px4-")}
    system_ids = sorted(int(s["environment"]["PX4_PARAM_MAV_SYS_ID"]) for s in sitl.values())
    assert system_ids == sorted(v["system_id"] for v in fleet["vehicles"])
    assert len(set(system_ids)) == len(system_ids) == 4
    for s in sitl.values():
        assert s["command"] == ["fleetplan"]  # where PX4 sends its offboard link
        assert s["networks"] == service["networks"]


@pytest.mark.slow
def test_wheel_carries_the_page_and_finds_it(tmp_path: Path) -> None:
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(ROOT)],
        capture_output=True, text=True, timeout=300,
    )
    assert build.returncode == 0, build.stderr
    wheel = next(tmp_path.glob("fleetplan-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert {"gcs/web/index.html", "gcs/web/main.js", "gcs/web/planview.js"} <= set(names)
    target = tmp_path / "site"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target),
         str(wheel)],
        capture_output=True, text=True, timeout=300,
    )
    assert install.returncode == 0, install.stderr
    probe = subprocess.run(
        [sys.executable, "-c",
         "from gcs.api.app import web_directory; from gcs.service.settings import Settings; "
         "print(web_directory(Settings()))"],
        capture_output=True, text=True, timeout=60, cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(target)},
    )
    assert probe.returncode == 0, probe.stderr
    assert Path(probe.stdout.strip()) == target / "gcs" / "web"


def test_make_run_leaves_host_and_port_to_the_settings() -> None:
    """`make run` must honour FLEETPLAN_HOST/FLEETPLAN_PORT: it passes no --host or --port."""
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    env = {**os.environ, "FLEETPLAN_PORT": "8123", "FLEETPLAN_HOST": "127.0.0.2"}
    done = subprocess.run(["make", "-n", "-W", "pyproject.toml", "run"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    serve = [line for line in done.stdout.splitlines() if "fleetplan serve" in line]
    assert serve, done.stdout
    assert all("--port" not in line and "--host" not in line for line in serve)


@pytest.mark.parametrize("name", ["fleetplan.db", "fleetplan.db-wal", "fleetplan.db-shm"])
def test_database_files_are_ignored_by_git(name: str) -> None:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    done = subprocess.run(["git", "check-ignore", "-q", name], cwd=ROOT, timeout=30)
    assert done.returncode == 0, f"{name} is not ignored"
