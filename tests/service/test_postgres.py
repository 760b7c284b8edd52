"""The same service on PostgreSQL: a throwaway server (Debian's postgresql binaries) in a
temporary directory, on a free port; missions, a flight and a restart through the real app."""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import QUICK_PAIR, free_port, free_udp_base, plan_mission, sse_events


def _as_server_user() -> tuple[list[str], int | None]:
    """PostgreSQL refuses to run as root: run its tools as the `postgres` user then."""
    if os.geteuid() != 0:
        return [], None
    try:
        uid = pwd.getpwnam("postgres").pw_uid
    except KeyError:
        pytest.skip("running as root and there is no 'postgres' user to run PostgreSQL as")
    return ["runuser", "-u", "postgres", "--"], uid


@pytest.fixture(scope="module")
def postgres_url() -> Iterator[str]:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    if not found:
        pytest.skip("PostgreSQL server not installed (sudo apt-get install postgresql); "
                    "`make test` installs it when run as root")
    bindir = Path(found[-1]).parent
    prefix, uid = _as_server_user()
    # Not under pytest's tmp_path: its parents are private to root, which PostgreSQL is not.
    top = Path(tempfile.mkdtemp(prefix="fleetplan-pg-"))
    data = top / "data"
    data.mkdir()
    if uid is not None:
        shutil.chown(top, user=uid)
        shutil.chown(data, user=uid)
    port = free_port()
    # A throwaway server: nothing is flushed to disk (the data dies with the test anyway).
    subprocess.run([*prefix, bindir / "initdb", "-D", data, "-A", "trust", "-U", "fleet",
                    "--no-sync"], check=True, capture_output=True, timeout=120)
    options = (f"-p {port} -k {data} -c listen_addresses=127.0.0.1 -c fsync=off "
               "-c synchronous_commit=off -c full_page_writes=off")
    subprocess.run([*prefix, bindir / "pg_ctl", "-D", data, "-w", "-l", data / "log",
                    "-o", options, "start"],
                   check=True, capture_output=True, timeout=120)
    try:
        subprocess.run([*prefix, bindir / "createdb", "-h", "127.0.0.1", "-p", str(port),
                        "-U", "fleet", "fleetplan"], check=True, capture_output=True, timeout=60)
        yield f"postgresql+psycopg://fleet@127.0.0.1:{port}/fleetplan"
    finally:
        subprocess.run([*prefix, bindir / "pg_ctl", "-D", data, "-m", "immediate", "stop"],
                       capture_output=True, timeout=60)
        shutil.rmtree(top, ignore_errors=True)


@pytest.mark.flight
@pytest.mark.slow
def test_missions_and_flights_on_postgresql(
    postgres_url: str, mock_settings: Callable[..., Settings]
) -> None:
    settings = mock_settings(database_url=postgres_url, mock_vehicles=2,
                             mock_base_port=free_udp_base(2))
    with TestClient(create_app(settings)) as client:
        mission = plan_mission(client, QUICK_PAIR)
        assert mission["plan"]["status"] == "converged"
        flight = client.post(f"/api/missions/{mission['id']}/flights",
                                json={"hold_at_goal": 0.5}).json()
        done = sse_events(client, flight["links"]["events"])[-1][1]
        assert done["status"] == "completed"
    with TestClient(create_app(settings)) as client:  # a restart keeps everything
        assert client.get(f"/api/missions/{mission['id']}").json() == mission
        stored = client.get(flight["links"]["self"]).json()
        assert stored["status"] == "completed" and stored["summary"] == done["summary"]
        listed = client.get("/api/flights", params={"mission_id": mission["id"]}).json()
        assert [f["event_count"] for f in listed["flights"]] == [len(stored["events"])]
        assert client.get(flight["links"]["record"]).status_code == 200
        assert client.delete(f"/api/missions/{mission['id']}").status_code == 204
        assert client.get(flight["links"]["self"]).status_code == 404
