"""`fleetplan serve` starting and stopping: the port check binds like uvicorn, database
problems are one line and exit 2, and a stop signal lands the fleet at once even with an
event stream open."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import pytest

from gcs.cli.main import build_parser
from gcs.cli.serve_cmd import overrides, port_free
from gcs.service.settings import Settings
from gcs.service.store import Store
from tests.api.support import QUICK_PAIR, ServiceProcess, free_port, free_udp_base
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(300)


def _time_wait_on(port: int) -> None:
    """Leave a TIME_WAIT connection on `port`: the listening side closes first, as a server
    closing its keep-alive connections on shutdown does."""
    with socket.socket() as listener:
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", port))
        listener.listen()
        client = socket.create_connection(("127.0.0.1", port))
        accepted, _ = listener.accept()
        accepted.close()  # server side first: it keeps the TIME_WAIT
        time.sleep(0.1)
        client.close()


def test_port_check_ignores_time_wait_but_not_a_listener() -> None:
    port = free_port()
    _time_wait_on(port)
    with socket.socket() as plain, pytest.raises(OSError):  # what the old check did
        plain.bind(("127.0.0.1", port))
    assert port_free(socket.SOCK_STREAM, port)
    with socket.socket() as listener:  # a real server on it (binding as uvicorn does)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", port))
        listener.listen()
        assert not port_free(socket.SOCK_STREAM, port)


def test_mock_n_is_a_fleet_of_n_and_mock_auto_one_that_grows(
    capsys, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)  # no ./fleetplan.toml, no FLEETPLAN_* of the developer's
    for name in [name for name in os.environ if name.startswith("FLEETPLAN_")]:
        monkeypatch.delenv(name)
    parser = build_parser()
    fixed = Settings(**overrides(parser.parse_args(["serve", "--mock", "6"])))
    assert (fixed.mock_vehicles, fixed.mock_fleet_limit) == (6, 6)
    for argv in (["serve", "--mock", "auto"], ["serve"]):  # auto is the default
        grows = Settings(**overrides(parser.parse_args(argv)))
        assert (grows.mock_vehicles, grows.mock_fleet_limit) == (4, 256)
    with pytest.raises(SystemExit) as exit_info:
        parser.parse_args(["serve", "--mock", "many"])
    assert exit_info.value.code == 2
    assert "--mock: 'many' is neither a vehicle count nor auto" in capsys.readouterr().err


def _serve(tmp_path: Path, db: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gcs.cli.main", "serve", "--port", str(free_port()),
         "--mock", "0", "--db", db],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
        env={k: v for k, v in os.environ.items() if not k.startswith("FLEETPLAN_")},
    )


@pytest.mark.parametrize(
    ("db", "message"),
    [
        ("sqlite:///{tmp}/no/such/dir/fleetplan.db", "unable to open database file"),
        ("sqlite:///file:{tmp}/ro.db?mode=ro&uri=true", "readonly database"),
    ],
    ids=["missing-directory", "read-only"],
)
def test_database_problems_are_one_line_and_exit_2(tmp_path: Path, db: str,
                                                   message: str) -> None:
    if "ro.db" in db:  # an existing database opened read-only
        Store(f"sqlite:///{tmp_path}/ro.db").close()
    result = _serve(tmp_path, db.format(tmp=tmp_path))
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("fleetplan serve: database ") and message in lines[0]
    assert "serving on" not in result.stdout


@pytest.mark.flight
def test_sigterm_lands_the_fleet_at_once_with_a_stream_open(tmp_path: Path) -> None:
    base = free_udp_base(2)
    service = ServiceProcess(tmp_path, "--mock", "2", "--workers", "1",
                             env={"FLEETPLAN_MOCK_BASE_PORT": str(base),
                                  "FLEETPLAN_MOCK_SETTLE_S": "0.5"}, quick_mocks=True)
    with service:
        url = service.base_url
        mission = httpx.post(f"{url}/api/missions?wait=120", json=QUICK_PAIR,
                             timeout=130).json()
        assert mission["status"] == "planned", mission
        # Six seconds of mission then a minute of holding: it would not end by itself soon.
        flight = httpx.post(f"{url}/api/missions/{mission['id']}/flights",
                               json={"hold_at_goal": 60}, timeout=30).json()
        events_url = f"{url}/api/flights/{flight['id']}/events"
        lines: list[str] = []
        stream_ended = threading.Event()

        def follow() -> None:
            with httpx.stream("GET", events_url, timeout=None) as response:
                for line in response.iter_lines():
                    lines.append(line)
            stream_ended.set()

        reader = threading.Thread(target=follow, daemon=True)
        reader.start()
        wait_for(lambda: (httpx.get(f"{url}/api/flights/{flight['id']}", timeout=30).json()
                          .get("live") or {}).get("phase") == "flying",
                 "the flight to fly its plan", timeout=60.0)
        assert service.process is not None
        began = time.monotonic()
        service.process.send_signal(signal.SIGTERM)
        service.process.wait(60)
        stopped_in = time.monotonic() - began
        assert stream_ended.wait(10), "the event stream stayed open"
        # Landing takes seconds; the flight would have gone on for over a minute.
        assert stopped_in < 40, stopped_in
    assert any(line.startswith("event:") for line in lines)  # the stream was live
    # What the stopped service stored (a restart on this database reads the same rows).
    store = Store(f"sqlite:///{tmp_path / 'fleetplan.db'}")
    try:
        stored = store.get_flight(flight["id"])
    finally:
        store.close()
    assert stored is not None
    assert stored.status == "aborted", stored
    assert stored.error is not None and "the service is stopping" in stored.error
    kinds = [event["kind"] for event in stored.events]
    assert "abort" in kinds
    # the stop lands the fleet by a landing plan, or PX4's Land when none was ready in its
    # bound on a busy machine: the events say which
    assert {"landing_plan", "landing_fallback"} & set(kinds), kinds


def test_an_unreachable_scheduler_is_a_one_line_problem() -> None:
    from gcs.cli.serve_cmd import scheduler_problem

    address = f"tcp://127.0.0.1:{free_port()}"
    problem = scheduler_problem(address, timeout=2)
    assert problem is not None
    assert problem.startswith(f"cannot reach the Dask scheduler at {address} (setting scheduler)")
    assert "\n" not in problem
    assert scheduler_problem(None) is None
