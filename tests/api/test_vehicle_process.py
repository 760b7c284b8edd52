"""The vehicle process as the API shows it: a process that ends is restarted so the fleet is
watched again; one that ends again at once is left stopped, and then every request that
needs the fleet answers 503 (never a 500) and GET /api/status reads degraded."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from typing import Any, cast

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(120)


def test_an_ended_vehicle_process_is_restarted_then_left_stopped_with_503s(
    mock_settings: Callable[..., Settings],
) -> None:
    with TestClient(create_app(mock_settings(mock_vehicles=2))) as client:
        service = cast(Any, client.app).state.fleet

        def pid() -> int | None:
            process = service.vehicle_process
            return process.pid if process.alive else None

        first = wait_for(pid, "the vehicle process")
        assert client.get("/api/status").json()["status"] == "ok"
        os.kill(first, signal.SIGKILL)
        second = wait_for(lambda: (p := pid()) is not None and p != first and p,
                          "a new vehicle process")
        vehicles = wait_for(lambda: (r := client.get("/api/vehicles")).status_code == 200
                            and len(r.json()["vehicles"]) == 2 and r.json(),
                            "the fleet watched again")
        assert vehicles["fleet"]["vehicle_process"] == "running"

        os.kill(second, signal.SIGKILL)  # again, at once: left stopped
        wait_for(lambda: client.get("/api/status").json()["status"] == "degraded",
                 "the status to read degraded")
        status = client.get("/api/status").json()
        assert status["fleet"]["vehicle_process"] == "stopped"
        for method, url, body in (("GET", "/api/vehicles", None),
                                  ("POST", "/api/fleet/commands", {"command": "land"})):
            answer = client.request(method, url, json=body)
            assert answer.status_code == 503, answer.text
            assert answer.headers["Retry-After"] == "5"
            assert answer.json()["field"] == "fleet"
            assert "vehicle process" in answer.json()["reason"]
