"""Test helpers: the bundled example scenarios, and `fleetplan serve` in a child process on a
free port for tests that need a real server (latency under load, fuzzing over HTTP, browser)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import httpx
from fastapi.testclient import TestClient
from httpx import Response

from gcs.sim import ports
from tests.paths import EXAMPLES
from tests.support.waiting import wait_for

__all__ = ["EXAMPLES", "GOALS", "OPERATOR", "OUT_AND_BACK", "QUICK", "QUICK_CROSSING",
           "QUICK_PAIR", "READER", "SHORT_CROSSING", "STARTS", "ServiceProcess", "example",
           "free_port", "free_udp_base", "plan_mission", "refused", "sse_events"]

#: Tokens the access tests configure: one that may operate, one that may only read.
OPERATOR = "operator-token-0123456789"
READER = "read-only-token-0123456789"


def refused(response: Response, status: int, field: str, reason: str) -> None:
    """`response` is the error `status` naming `field`, its reason containing `reason`."""
    assert response.status_code == status, response.text
    body = response.json()
    assert body["status"] == status and body["field"] == field, body
    assert reason in body["reason"], body


def example(name: str) -> dict[str, Any]:
    """A scenario bundled with the planner, as JSON."""
    return json.loads((EXAMPLES / f"{name}.json").read_text())


#: Four vehicles crossing near the centre in 10 s: a quick flight for the mock fleet.
SHORT_CROSSING: dict[str, Any] = {
    "name": "short-crossing", "dt": 0.2, "steps": 50, "min_separation": 1.0,
    "limits": {"position_min": [0, 0, 0], "position_max": [6, 6, 3], "velocity_max": [2, 2, 2],
               "acceleration_max": [3, 3, 3], "jerk_max": [5, 5, 5]},
    "vehicles": [
        {"id": "a", "start": [1.0, 2.8, 1.2], "goal": [4.5, 3.3, 1.4]},
        {"id": "b", "start": [4.5, 3.0, 1.6], "goal": [1.0, 3.2, 1.5]},
        {"id": "c", "start": [2.9, 1.0, 1.3], "goal": [3.1, 4.6, 1.7]},
        {"id": "d", "start": [3.1, 4.8, 1.8], "goal": [2.8, 1.2, 1.2]},
    ],
}


#: The same crossing in 6 s: for tests that fly to the end and need no time inside the flight.
QUICK_CROSSING: dict[str, Any] = {**SHORT_CROSSING, "name": "quick-crossing", "steps": 30}


#: Two vehicles crossing in 6 s at 0.6-0.8 m: a short climb and landing, for tests that need
#: a fleet in the air (or one whole flight) and nothing of a larger one.
QUICK_PAIR: dict[str, Any] = {
    **QUICK_CROSSING, "name": "quick-pair",
    "vehicles": [
        {"id": "a", "start": [1.0, 2.8, 0.6], "goal": [4.5, 3.3, 0.8]},
        {"id": "b", "start": [4.5, 3.0, 0.8], "goal": [1.0, 3.2, 0.7]},
    ],
}


def free_udp_base(count: int) -> int:
    """A mock base port whose every port (`gcs.sim.ports` rule) is free now: never PX4's."""
    return ports.free_udp_base(ports.mock_port_offsets(count))


def free_port() -> int:
    """A TCP port nobody listens on right now (chosen by the OS)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class ServiceProcess:
    """`python -m gcs.cli.main serve ...` with its own database under `workdir`; with
    `quick_mocks`, its mock vehicles get `FAST_MOCK`'s timings (`QUICK_MOCK_ENV`)."""

    def __init__(self, workdir: Path, *args: str, env: dict[str, str] | None = None,
                 token: str | None = None, start_timeout: float = 120.0,
                 quick_mocks: bool = False) -> None:
        self.workdir = workdir
        #: How long `with ServiceProcess(...)` waits for the service to answer (s): a loose
        #: bound, as `start`'s: at load 30 a service can take over a minute to answer.
        self.start_timeout = start_timeout
        #: The API token the service is configured with (sent while waiting for it), if any.
        self.headers = {} if token is None else {"Authorization": f"Bearer {token}"}
        self.port = free_port()
        self.base_url = f"http://127.0.0.1:{self.port}"
        self.log_path = workdir / f"serve-{self.port}.log"
        self.command = [
            sys.executable, "-m", "gcs.cli.main", "serve",
            "--host", "127.0.0.1", "--port", str(self.port),
            "--db", f"sqlite:///{workdir / 'fleetplan.db'}",
            *args,
        ]
        from tests.flight.support import QUICK_MOCK_ENV

        self.env = {**os.environ, "PYTHONUNBUFFERED": "1",
                    **(QUICK_MOCK_ENV if quick_mocks else {}), **(env or {})}
        self.process: subprocess.Popen[bytes] | None = None

    def start(self, timeout: float = 120.0) -> ServiceProcess:
        log = self.log_path.open("wb")
        self.process = subprocess.Popen(
            self.command, cwd=self.workdir, env=self.env, stdout=log, stderr=subprocess.STDOUT
        )
        process = self.process

        def answers() -> bool:
            if process.poll() is not None:
                raise RuntimeError(f"fleetplan serve exited:\n{self.log()}")
            try:
                return httpx.get(f"{self.base_url}/api/status", headers=self.headers,
                                 timeout=5.0).status_code == 200
            except httpx.HTTPError:
                return False

        try:
            wait_for(answers, "fleetplan serve to answer /api/status", timeout,
                     detail=lambda: f"its log:\n{self.log()}")
        except AssertionError:
            self.stop()
            raise
        return self

    def log(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def stop(self) -> None:
        if self.process is None or self.process.poll() is not None:
            return
        self.process.terminate()
        try:
            self.process.wait(15)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(5)

    def __enter__(self) -> ServiceProcess:
        return self.start(self.start_timeout)

    def __exit__(self, *exc: object) -> None:
        self.stop()


def plan_mission(client: TestClient, scenario: dict[str, Any]) -> dict[str, Any]:
    """POST a scenario and wait (up to a minute) for its plan."""
    response = client.post("/api/missions?wait=60", json=scenario)
    assert response.status_code == 201, response.text
    return response.json()


def sse_events(client: TestClient, url: str) -> list[tuple[str, dict[str, Any]]]:
    """Every (event, data) of a server-sent event stream, until the server ends it."""
    events: list[tuple[str, dict[str, Any]]] = []
    kind = None
    with client.stream("GET", url) as response:
        assert response.status_code == 200
        assert response.headers["content-type"].startswith("text/event-stream")
        for line in response.iter_lines():
            if line.startswith("event:"):
                kind = line.split(":", 1)[1].strip()
            elif line.startswith("data:"):
                events.append((kind or "message", json.loads(line.split(":", 1)[1])))
    return events


#: Quick flights: half a second at the goals, a 2 m/s climb after a 0.3 s prestream. A
#: vehicle is flagged 2 m (not 1 m) off its plan: on a loaded machine the station and its
#: in-process mocks stall together and a vehicle falls behind while both catch up; the
#: flight's accuracy is what these tests judge by its goal errors and separation (tracking
#: is tested in tests/flight).
QUICK = {"hold_at_goal": 0.5, "tracking_error_max": 2.0, "climb_speed": 2.0, "prestream": 0.3}

#: SHORT_CROSSING's starts and goals, as formations.
STARTS = [v["start"] for v in SHORT_CROSSING["vehicles"]]
GOALS = [v["goal"] for v in SHORT_CROSSING["vehicles"]]


#: Four vehicles out and back between two formations with short holds: 13.2 s in all.
OUT_AND_BACK: dict[str, Any] = {
    "name": "out-and-back",
    "dt": 0.2,
    "min_separation": 1.0,
    "limits": SHORT_CROSSING["limits"],
    "vehicles": ["a", "b", "c", "d"],
    "formations": [
        {"name": "home", "positions": STARTS, "hold": 0.4},
        {"name": "crossed", "positions": GOALS, "duration": 6, "hold": 0.4},
        {"name": "home", "positions": STARTS, "duration": 6, "hold": 0.4},
    ],
}
