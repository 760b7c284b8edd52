"""A show with lights that takes off from a ground grid, planned through the service: the
mission's plan loads and verifies, and its .skyc download carries each drone's takeoffTime
and light program."""

from __future__ import annotations

import base64
import io
import json
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from planner import Plan
from tests.support.shows import ground_show as _show
from tests.support.shows import post_sequence


@pytest.fixture
def client(tmp_path: Path, dask_scheduler: str) -> Iterator[TestClient]:
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'fleetplan.db'}",
                        mock_vehicles=0, plan_workers=1, scheduler=dask_scheduler,
                        allowed_hosts=["testserver"])
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def test_a_ground_show_is_a_mission_whose_file_takes_off(client: TestClient) -> None:
    body = _show(landing={})
    body["formations"][0]["color"] = "#ff8800"
    mission = post_sequence(client, body)  # planned within its wait: 201
    assert mission["plan_ok"] is True, mission["error"]
    plan = Plan.from_dict(client.get(mission["links"]["plan"]).json())
    assert plan.ok and plan.sequence is not None and "ground" in plan.sequence
    download = client.get(f"/api/missions/{mission['id']}/show.skyc")
    assert download.status_code == 200, download.text
    with zipfile.ZipFile(io.BytesIO(download.content)) as archive:
        show = json.loads(archive.read("show.json"))
    liftoff = plan.sequence["ground"]["takeoff"]["liftoff_s"]
    for drone in show["swarm"]["drones"]:
        settings = drone["settings"]
        assert settings["trajectory"]["takeoffTime"] == pytest.approx(liftoff[settings["name"]])
        program = base64.b64decode(settings["lights"]["data"])
        assert program[:4] == bytes([0x04, 0xFF, 0x88, 0x00])  # SET_COLOR the first colour
