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
from pymavlink import mavutil

from gcs.fleet.fleetfile import FleetSpec
from gcs.flight.link.hub import LinkHub
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


def test_mock_status_rate_sets_how_often_the_vehicles_report_their_state() -> None:
    """--status-rate 5: HEARTBEAT at 5 Hz beside LOCAL_POSITION_NED at 30 Hz (counted as a
    ratio of the two, which a busy machine slows alike), where PX4's default is 1 Hz."""
    base = free_port_block(2)
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{base}", source_system=255)
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", "1", "--status-rate", "5",
         "--settle", "0", "--base-port", str(base), "--listen-base-port", str(base + 1),
         "--duration", "4"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    counts = {"HEARTBEAT": 0, "LOCAL_POSITION_NED": 0}
    try:
        while proc.poll() is None or counts["LOCAL_POSITION_NED"] == 0:
            message = gcs.recv_match(type=list(counts), blocking=True, timeout=1.0)
            if message is None:
                if proc.poll() is not None:
                    break
                continue
            counts[message.get_type()] += 1
        out, _ = proc.communicate(timeout=20)
    finally:
        gcs.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, out
    assert counts["LOCAL_POSITION_NED"] >= 30, counts
    # 5/30 = 0.17 here; PX4's 1 Hz would give 0.03
    assert counts["HEARTBEAT"] / counts["LOCAL_POSITION_NED"] > 0.1, counts


@pytest.mark.parametrize("extra, says", [
    (("--position-error", "20"), "--position-error must be within [0, 10] m"),
    (("--settle", "nan"), "--settle must be a finite number"),
    (("--position-rate", "0"), "--position-rate must be above 0"),
    (("--seed", "-1"), "--seed must be an integer in [0, 2^32)"),
    (("--status-rate", "0"), "--status-rate must be within (0, 50] Hz"),
    (("--land-speed", "5"), "--land-speed must be within [0.2, 3] m/s"),
    (("--disarm-after-land", "inf"), "--disarm-after-land must be within [0.1, 20] s"),
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
