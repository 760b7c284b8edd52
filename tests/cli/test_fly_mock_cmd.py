"""The `fleetplan fly` and `fleetplan mock` commands, as a user runs them."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.flight.support import STACKED, free_port_block, short_line, smooth_plan
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(90)


def _fly(tmp_path: Path, *extra: str) -> subprocess.Popen:
    """`fleetplan fly --mock` of two vehicles flying 2 m in 3 s at 1 m, in the background; the
    mocks report their state at 5 Hz, land at 1 m/s and disarm 0.5 s after touchdown, so the
    flight's mode changes and its landing take less time than PX4's defaults would."""
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(short_line(2)).to_dict()))
    base = free_port_block(4)
    return subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path), "--mock",
         "--mock-settle", "0.5", "--mock-status-rate", "5", "--mock-land-speed", "1",
         "--mock-disarm-after-land", "0.5", "--hold-at-goal", "0.5", "--climb-speed", "2",
         "--prestream", "0.3", "--base-port", str(base),
         "--listen-base-port", str(base + 2), "--record", str(tmp_path / "record.json"),
         *extra], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _flying(tmp_path: Path) -> subprocess.Popen:
    """`_fly`, returned once its output says the plan is being flown (or after 60 s)."""
    proc = _fly(tmp_path)
    assert proc.stdout is not None
    deadline = time.monotonic() + 60
    for line in proc.stdout:
        if "flight_start" in line or time.monotonic() > deadline:
            break
    return proc


@pytest.mark.flight
def test_fly_mock_completes_and_records(tmp_path: Path) -> None:
    proc = _fly(tmp_path)
    out, _ = proc.communicate(timeout=80)
    assert proc.returncode == 0, out
    assert "completed               True" in out
    record = json.loads((tmp_path / "record.json").read_text())
    summary = record["summary"]
    assert summary["completed"] is True and summary["goal_error_max"] < 0.2
    assert (record["options"]["climb_speed"], record["options"]["prestream"]) == (2.0, 0.3)
    assert set(summary) >= {"completed", "goal_error_max", "tracking_error_max",
                            "min_separation_measured", "setpoint_rate_hz", "jitter_p99_ms"}


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.flight
def test_ctrl_c_lands_everyone(tmp_path: Path, sig: signal.Signals) -> None:
    """Ctrl-C (or SIGTERM, e.g. from a service manager) mid-plan lands every vehicle by a
    verified landing plan, then PX4's Land, and waits for them to disarm."""
    proc = _flying(tmp_path)
    time.sleep(0.2)  # into the 3 s plan
    proc.send_signal(sig)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 1, out
    assert "FlightAborted" in out
    record = json.loads((tmp_path / "record.json").read_text())
    # by a landing plan, or (a machine too busy for its 0.5 s bound) PX4's Land: one of the
    # two, which the events say (tests/flight/test_landing.py flies the landing plan itself)
    kinds = [e["kind"] for e in record["events"]]
    assert ("landing_plan" in kinds) != ("landing_fallback" in kinds), out
    landed = {e["vehicle"] for e in record["events"] if e["kind"] == "landed"}
    assert landed == {"uav1", "uav2"}
    for v in record["vehicles"]:
        assert v["modes"][-1]["armed"] is False


def test_fly_rejects_bad_fleet_file(tmp_path: Path) -> None:
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(short_line(2)).to_dict()))
    fleet = tmp_path / "fleet.json"
    fleet.write_text(json.dumps({"vehicles": [{"id": "uav1", "connection": "udpin:x",
                                               "system_id": 1, "home": [0, 0, 0]}]}))
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path),
                           "--fleet", str(fleet)], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2
    assert "vehicles[0].connection" in proc.stderr


def test_mock_on_a_busy_port_is_one_line(tmp_path: Path) -> None:
    import socket

    base = free_port_block(2)
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", base + 1))  # vehicle 0's listen port
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "gcs.cli.main", "mock", "--vehicles", "1",
             "--base-port", str(base), "--listen-base-port", str(base + 1), "--duration", "1"],
            capture_output=True, text=True, timeout=30)
    finally:
        busy.close()
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(base + 1) in lines[0]
    assert "choose free ports with --base-port and --listen-base-port" in lines[0]


def test_fly_mock_on_a_busy_port_names_the_options(tmp_path: Path) -> None:
    import socket

    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(short_line(1)).to_dict()))
    base = free_port_block(2)
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", base + 1))  # the mock vehicle's listen port
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path), "--mock",
             "--base-port", str(base), "--listen-base-port", str(base + 1)],
            capture_output=True, text=True, timeout=30)
    finally:
        busy.close()
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "--base-port (the GCS side) and --listen-base-port (the mock vehicles)" \
        in proc.stderr


@pytest.mark.flight
def test_fly_mock_climbs_stacked_starts_one_after_the_other(tmp_path: Path) -> None:
    """Mocks set down under starts 0.55 m apart horizontally (R = 1 m): the higher climbs
    first, the lower after it, and the flight completes."""
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(STACKED).to_dict()))
    base = free_port_block(4)
    proc = subprocess.run(
        [sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path), "--mock",
         "--mock-settle", "0.5", "--mock-status-rate", "5", "--mock-land-speed", "1",
         "--mock-disarm-after-land", "0.5", "--hold-at-goal", "0.5", "--climb-speed", "2",
         "--prestream", "0.3", "--base-port", str(base), "--listen-base-port", str(base + 2)],
        capture_output=True, text=True, timeout=90)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "low: climb climbs in wave 2 of 2" in proc.stdout, proc.stdout


def test_fly_given_a_scenario_says_to_plan_it_first(tmp_path: Path) -> None:
    scenario = tmp_path / "scenario.json"
    scenario.write_text(json.dumps(short_line(2)))
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", "fly", str(scenario),
                           "--mock"], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (f"error: {scenario} is a scenario, not a plan: plan it "
                                   f"first (fleetplan plan {scenario} -o PLAN.json), then fly "
                                   "PLAN.json")


def test_fly_with_nothing_listening_names_the_port_and_the_mock(tmp_path: Path) -> None:
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(short_line(1)).to_dict()))
    port = free_port_block(1)
    fleet = tmp_path / "fleet.json"
    fleet.write_text(json.dumps({
        "vehicles": [{"id": "uav1", "connection": f"udpin:127.0.0.1:{port}", "system_id": 1,
                      "home": [0, 0, 0]}],
        "flight": {"connect_timeout": 0.5}}))
    proc = subprocess.run([sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path),
                           "--fleet", str(fleet)], capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert f"no HEARTBEAT within 0.5 s on udpin:127.0.0.1:{port}" in proc.stderr
    assert "nothing at all arrived there" in proc.stderr and "fleetplan mock" in proc.stderr


@pytest.mark.flight
def test_packets_from_a_foreign_source_are_warned_live(tmp_path: Path) -> None:
    """Another process sending as uav1 to its GCS port during the flight (a second fly on
    the same ports) is warned on stderr as it happens, even with --quiet, naming the options
    that choose other ports; the record counts the drops too."""
    import socket
    import threading

    from pymavlink.dialects.v20 import common as mavlink

    proc = _fly(tmp_path, "--quiet")
    assert proc.stdout is not None
    base = int(proc.args[proc.args.index("--base-port") + 1])  # uav1's GCS port
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    packet = mav.heartbeat_encode(2, 12, 0, 0, 0).pack(mav)
    stop = threading.Event()

    def intrude() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other:
            while not stop.wait(0.2):
                other.sendto(packet, ("127.0.0.1", base))

    intruder = threading.Thread(target=intrude, daemon=True)
    intruder.start()
    lines = []
    try:
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("warning: uav1:"):
                break
    finally:
        stop.set()
        intruder.join(5)
    out, _ = proc.communicate(timeout=60)
    warned = [line for line in lines if line.startswith("warning: uav1:")]
    assert warned, "".join(lines) + out
    assert "foreign_source" in warned[0] and "the latest from 127.0.0.1:" in warned[0]
    assert "another fleetplan fly or mock" in warned[0]
    assert "--base-port (the GCS side) and --listen-base-port" in warned[0]
    record = json.loads((tmp_path / "record.json").read_text())
    assert any(e["kind"] == "dropped_packets" and e["vehicle"] == "uav1"
               for e in record["events"])


@pytest.mark.flight
def test_sigusr1_pauses_and_sigusr2_resumes(tmp_path: Path) -> None:
    proc = _fly(tmp_path)
    assert proc.stdout is not None
    lines = []
    for line in proc.stdout:  # wait until the plan is being flown
        lines.append(line)
        if "flight_start" in line:
            break
    time.sleep(0.2)  # into the 3 s plan
    proc.send_signal(signal.SIGUSR1)
    for line in proc.stdout:
        lines.append(line)
        if "paused at flight time" in line:
            break
    time.sleep(1.0)  # paused this long at least
    proc.send_signal(signal.SIGUSR2)
    out, _ = proc.communicate(timeout=60)
    out = "".join(lines) + out
    assert proc.returncode == 0, out
    assert "resumed at flight time" in out
    record = json.loads((tmp_path / "record.json").read_text())
    [[start, end]] = record["pauses"]
    assert end - start >= 1.0
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index("pause") < kinds.index("resume") < kinds.index("landed")
    assert record["summary"]["completed"] is True


@pytest.mark.flight
def test_fly_mock_realism_px4_with_realtime_streaming(tmp_path: Path) -> None:
    """`--mock-realism px4` flies PX4-like vehicles, `--mock-position-error` states the
    fleet's position error (goal tolerance 2 x 0.25 m instead of the fixed 0.2 m) and
    `--stream-priority` reaches the stream (recorded)."""
    # (the plan has no margin for that error: flown anyway with a warning)
    proc = _fly(tmp_path, "--mock-realism", "px4", "--mock-position-error", "0.25",
                "--margin-check", "warn", "--stream-priority", "realtime", "-q")
    out, _ = proc.communicate(timeout=80)
    record = json.loads((tmp_path / "record.json").read_text())
    assert proc.returncode == (0 if record["summary"]["completed"] else 1), out
    tolerances = record["summary"]["goal_tolerances"]
    assert set(tolerances) == {"uav1", "uav2"}
    assert all(t == pytest.approx(0.5) for t in tolerances.values()), tolerances
    assert record["events"][0]["kind"] == "margin_warning", record["events"][0]
    assert [e["kind"] for e in record["events"]].count("stream_priority") == 1


@pytest.mark.parametrize("extra, says", [
    (("--stream-priority", "fastest"), "--stream-priority"),
    (("--mock-position-error", "-1"), "position_error"),
    (("--climb-speed", "0"), "climb_speed"),
    (("--prestream", "-1"), "prestream"),
    (("--mock-land-speed", "0.1"), "--mock-land-speed must be within [0.2, 3] m/s"),
    (("--mock-settle", "nan"), "--mock-settle must be within [0, 60] s"),
])
def test_fly_rejects_bad_options(tmp_path: Path, extra: tuple[str, ...], says: str) -> None:
    proc = _fly(tmp_path, *extra)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 2 and says in out and "Traceback" not in out, out


@pytest.mark.flight
def test_a_killed_fly_leaves_a_readable_partial_record(tmp_path: Path) -> None:
    """kill -9 mid-plan: no final write, yet the record file holds the record so far
    (written about once a second as the flight goes): a whole JSON document marked
    partial, with the events up to the plan's start and each vehicle's telemetry."""
    proc = _flying(tmp_path)
    path = tmp_path / "record.json"

    def started() -> bool:  # the next write after the plan's start
        record = json.loads(path.read_text()) if path.exists() else {"events": []}
        return any(e["kind"] == "flight_start" for e in record["events"])

    try:
        wait_for(started, "a record written after the plan's start", timeout=60.0, poll=0.1)
    finally:
        proc.kill()
    proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    record = json.loads(path.read_text())
    assert record["partial"] is True and record["summary"] is None
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index("connected") < kinds.index("armed") < kinds.index("flight_start")
    assert [v["id"] for v in record["vehicles"]] == ["uav1", "uav2"]
    for v in record["vehicles"]:
        assert len(v["telemetry"]["t"]) > 10 and len(v["setpoints"]["t"]) > 10
        assert v["modes"][0]["mode"]
