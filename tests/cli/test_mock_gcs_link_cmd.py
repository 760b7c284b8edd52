"""`fleetplan mock --gcs-port` and `fleetplan fly --mock --mock-gcs-port`: the GCS link a
ground station watches, and a bad port refused with the option's name."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gcs.wire import mavlink
from tests.flight.support import free_port_block, short_line, smooth_plan
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(60)


def test_mock_gcs_port_sends_to_a_ground_station() -> None:
    base = free_port_block(2)
    station = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    station.bind(("127.0.0.1", 0))
    station.settimeout(0.5)
    port = station.getsockname()[1]
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", "1", "--base-port",
         str(base), "--listen-base-port", str(base + 1), "--gcs-port", str(port),
         "--duration", "20"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True

        def heartbeat_heard() -> Any:
            """A HEARTBEAT in the next datagram (each read waits up to 0.5 s)."""
            try:
                data, _source = station.recvfrom(4096)
            except TimeoutError:
                return None
            return next((m for m in parser.parse_buffer(data) or []
                         if m.get_type() == "HEARTBEAT"), None)

        heartbeat = wait_for(heartbeat_heard, "a HEARTBEAT on the GCS port", timeout=20.0,
                             poll=0.0)
        assert heartbeat.get_srcSystem() == 1
        assert heartbeat.autopilot == mavlink.MAV_AUTOPILOT_PX4
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=10)
        station.close()
    assert f"GCS links send to 127.0.0.1:{port}" in out


@pytest.mark.parametrize("command", ["mock", "fly"])
def test_a_bad_gcs_port_is_refused(command: str, tmp_path: Path) -> None:
    if command == "mock":
        args = ["mock", "--vehicles", "1", "--gcs-port", "70000"]
        flag = "--gcs-port"
    else:
        plan_path = tmp_path / "plan.json"
        plan_path.write_text(json.dumps(smooth_plan(short_line(1)).to_dict()))
        args = ["fly", str(plan_path), "--mock", "--mock-gcs-port", "0"]
        flag = "--mock-gcs-port"
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", *args],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"error: {flag} must be a UDP port (1..65535)")


@pytest.mark.parametrize(("args", "error"), [
    (["mock", "--vehicles", "2", "--base-port", "70000"],
     "error: --base-port 70000 with 2 vehicles needs UDP ports 70000..70001: give a base port "
     "from 1 to 65534"),
    (["mock", "--vehicles", "10", "--listen-base-port", "65530"],
     "error: --listen-base-port 65530 with 10 vehicles needs UDP ports 65530..65539"),
    (["mock", "--vehicles", "1", "--loss", "2"],
     "error: --loss must be a fraction within [0, 1], got 2.0"),
    (["mock", "--vehicles", "1", "--delay", "nan"],
     "error: --delay must be a finite number of seconds >= 0, got nan"),
    (["fly", "PLAN", "--mock", "--listen-base-port", "70000"],
     "error: --listen-base-port 70000 with 1 vehicle needs UDP ports 70000..70000"),
    (["fly", "PLAN", "--mock", "--base-port", "65536"],
     "error: --base-port 65536 with 1 vehicle needs UDP ports 65536..65536"),
])
def test_a_port_block_or_a_radio_fault_out_of_range_is_refused_before_anything_starts(
        args: list[str], error: str, tmp_path: Path) -> None:
    """The mocks' ports must all be UDP ports (binding one past 65535 raised OverflowError, a
    traceback), and the radio faults must be a fraction and a delay."""
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(short_line(1)).to_dict()))
    args = [str(plan_path) if a == "PLAN" else a for a in args]
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", *args],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.startswith(error), proc.stderr
