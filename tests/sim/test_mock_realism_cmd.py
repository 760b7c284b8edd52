"""`fleetplan mock --realism px4` as a user runs it: the fleet file it writes, the accuracy its
vehicles report, and one-line errors for bad options."""

from __future__ import annotations

import asyncio
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from gcs.flight.fleetfile import FleetSpec
from gcs.flight.hub import LinkHub
from gcs.sim.model import EstimateNoise
from tests.flight.support import free_port_block

pytestmark = pytest.mark.timeout(60)


def _mock(*extra: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "gcs.cli.main", "mock", *extra],
                          capture_output=True, text=True, timeout=timeout)


def test_mock_realism_px4_runs_px4_like_vehicles(tmp_path: Path) -> None:
    base = free_port_block(4)
    fleet_path = tmp_path / "fleet.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", "2", "--realism", "px4",
         "--seed", "3", "--base-port", str(base), "--listen-base-port", str(base + 2),
         "--fleet-out", str(fleet_path), "--position-error", "0.25", "--duration", "6"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        assert "(px4)" in first, first
        fleet = FleetSpec.from_dict(json.loads(fleet_path.read_text()))
        assert fleet.position_error == pytest.approx(0.25)

        async def accuracy() -> tuple[float, float]:
            async with LinkHub() as hub:
                spec = fleet.vehicles[1]
                link = await hub.add(spec.id, spec.connection, spec.system_id)
                assert await link.wait_for(lambda t: not math.isnan(t.gps_h_acc), 5.0)
                return link.telemetry.gps_h_acc, link.telemetry.gps_v_acc

        h_acc, v_acc = asyncio.run(accuracy())
        assert h_acc == pytest.approx(EstimateNoise().horizontal_accuracy, abs=1e-3)
        assert v_acc == pytest.approx(EstimateNoise().vertical_accuracy, abs=1e-3)
        out, _ = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, out


@pytest.mark.parametrize("extra, says", [
    (("--position-error", "20"), "--position-error must be within [0, 10] m"),
    (("--settle", "nan"), "--settle must be a finite number"),
    (("--position-rate", "0"), "--position-rate must be above 0"),
    (("--seed", "-1"), "--seed must be an integer in [0, 2^32)"),
])
def test_bad_mock_options_are_one_line_errors(extra: tuple[str, ...], says: str) -> None:
    proc = _mock("--vehicles", "1", "--duration", "1", *extra)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0], proc.stderr


def test_an_unknown_realism_is_refused() -> None:
    proc = _mock("--realism", "gazebo", "--duration", "1")
    assert proc.returncode == 2 and "--realism" in proc.stderr and "Traceback" not in proc.stderr
