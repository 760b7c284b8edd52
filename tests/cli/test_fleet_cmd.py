"""`fleetplan fleet COMMAND --fleet FLEET.json`: landing a fleet left hovering, as a user does."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.run.executor import FlightExecutor
from gcs.sim import MockFleet, homes_under
from tests.flight.support import FAST_MOCK, QUICK, mock_ports, short_line, smooth_plan

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def hovering(tmp_path: Path) -> Iterator[tuple[Path, MockFleet]]:
    """Two mock vehicles (on a thread of their own) that flew a 3 s plan and stayed hovering
    in PX4 Hold (`at_end: hold`), and their fleet file."""
    plan = smooth_plan(short_line(2))
    ready = threading.Event()
    stop = threading.Event()
    holder: dict[str, object] = {}

    async def serve() -> None:
        homes = homes_under(plan.scenario.starts)
        settings: dict[str, Any] = {"settle_time": 0.5, **FAST_MOCK, **mock_ports(2)}
        async with MockFleet(homes=homes, **settings) as mock:
            fleet = mock.fleet_dict(plan.scenario.ids)
            executor = FlightExecutor(plan, FleetSpec.from_dict(fleet),
                                      QUICK.replace(at_end="hold"))
            try:
                holder["record"] = await executor.run()
            except Exception as exc:  # reported by the fixture below
                holder["error"] = exc
            holder["mock"], holder["fleet"] = mock, fleet
            ready.set()
            await asyncio.to_thread(stop.wait)  # serving until the fixture's teardown

    thread = threading.Thread(target=lambda: asyncio.run(serve()), daemon=True)
    thread.start()
    try:
        assert ready.wait(60), "the flight did not end"
        assert "error" not in holder, holder.get("error")
        path = tmp_path / "fleet.json"
        path.write_text(json.dumps(holder["fleet"]))
        yield path, holder["mock"]  # type: ignore[misc]
    finally:
        stop.set()
        thread.join(10)


def _fleet(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "gcs.cli.main", "fleet", *args],
                          capture_output=True, text=True, timeout=90)


@pytest.mark.flight
def test_fleet_land_lands_a_hovering_fleet(hovering: tuple[Path, MockFleet]) -> None:
    path, mock = hovering
    assert all(v.armed and v.in_air for v in mock.vehicles)
    refused = _fleet("disarm", "--fleet", str(path))
    assert refused.returncode == 2 and "in the air" in refused.stderr
    unconfirmed = _fleet("terminate", "--fleet", str(path))
    assert unconfirmed.returncode == 2 and "confirm" in unconfirmed.stderr
    unknown = _fleet("land", "--fleet", str(path), "--vehicle", "uav7")
    assert unknown.returncode == 2 and "uav7" in unknown.stderr
    assert all(v.armed and v.in_air for v in mock.vehicles)

    one = _fleet("land", "--fleet", str(path), "--vehicle", "uav2")
    assert one.returncode == 0, one.stdout + one.stderr
    assert "uav2: done: landing" in one.stdout and "uav2: landed and disarmed" in one.stdout
    assert not mock.vehicles[1].armed and mock.vehicles[0].armed
    everyone = _fleet("land", "--fleet", str(path))
    assert everyone.returncode == 0, everyone.stdout + everyone.stderr
    assert "uav1: landed and disarmed" in everyone.stdout
    assert "already disarmed" in everyone.stdout  # uav2
    assert not any(v.armed for v in mock.vehicles)
    assert all(v.position_ned[2] == pytest.approx(0.0, abs=0.05) for v in mock.vehicles)


def test_fleet_rejects_a_bad_fleet_file(tmp_path: Path) -> None:
    path = tmp_path / "fleet.json"
    path.write_text("{")
    proc = _fleet("land", "--fleet", str(path))
    assert proc.returncode == 2 and "not valid JSON" in proc.stderr
