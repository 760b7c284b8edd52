"""`fleetplan fly --mock --control PATH` replanned by `fleetplan replan PATH` mid-flight, as a
user runs them: the replan is flown (new goal, a vehicle dropped to land), the flight
completes, and the socket is gone after."""

from __future__ import annotations

import json
import queue
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from gcs import phases
from gcs.cli.main import main
from tests.flight.support import free_port_block, line_scenario, smooth_plan
from tests.support.waiting import line_with, wait_for

pytestmark = [pytest.mark.timeout(150),
              pytest.mark.skipif(not hasattr(phases, "ReplanStatus"),
                                 reason="needs FlightExecutor.replan (wt/flight)")]


def _lines(proc: subprocess.Popen[str]) -> tuple[queue.Queue[str], threading.Thread]:
    """The process's output lines, read on a thread (so a wait can time out), until it
    closes its output; the thread."""
    lines: queue.Queue[str] = queue.Queue()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.put(line)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    return lines, reader


def _replan_started(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "gcs.cli.main", "replan", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.flight
def test_fly_takes_a_replan_on_its_control_socket(tmp_path: Path) -> None:
    # Three vehicles 3 m apart flying 2 m along y in 10 s at 1.5 m.
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(line_scenario(3, steps=50)).to_dict()))
    sock = tmp_path / "fly.sock"
    base = free_port_block(6)
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs.cli.main", "fly", str(plan_path), "--mock",
         "--mock-settle", "0.5", "--mock-status-rate", "5", "--mock-land-speed", "1",
         "--mock-disarm-after-land", "0.5", "--hold-at-goal", "0.5", "--climb-speed", "2",
         "--prestream", "0.3", "--base-port", str(base), "--listen-base-port", str(base + 3),
         "--record", str(tmp_path / "record.json"), "--control", str(sock),
         "--replan-lead", "5"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    seen: list[str] = []
    try:
        lines, reader = _lines(proc)
        for text in (f"control socket: {sock}", "flight_start"):
            wait_for(line_with(lines, text, seen), f"{text!r} in fly's output", timeout=60.0,
                     detail=lambda: "".join(seen))
        # One at a time: two identical requests sent together (a busy machine may take
        # seconds to start each command): one is taken, the other refused while the first
        # waits for its switch.
        asked = [_replan_started(str(sock), "--goal", "uav1=1,2,2", "--drop", "uav3")
                 for _ in range(2)]
        answers = sorted((p.wait(timeout=60), *p.communicate()) for p in asked)
        (ok, out_ok, _), (refused, _, err_refused) = answers
        assert ok == 0 and refused == 1, answers
        replan = json.loads(out_ok)
        assert replan["status"] == "planning" and replan["drop"] == ["uav3"]
        assert "refused (StateConflict)" in err_refused
        proc.wait(timeout=90)
        reader.join(timeout=10)  # the rest of its output
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    while not lines.empty():
        seen.append(lines.get())
    out = "".join(seen)
    assert proc.returncode == 0, out
    assert "replan_switched" in out and "replan_missed" not in out
    assert not sock.exists()  # removed at the end
    record = json.loads((tmp_path / "record.json").read_text())
    [flown] = record["replans"]
    assert flown["status"] == "switched" and flown["goals"] == {"uav1": [1.0, 2.0, 2.0]}
    assert record["summary"]["completed"] is True and "uav3" in record["summary"]["dropped"]
    assert {e["vehicle"] for e in record["events"] if e["kind"] == "landed"} >= {"uav3"}


@pytest.mark.parametrize(("flags", "message"), [
    (["--policy", "nope"], "option.policy: must be one of hold_all, land_all, land_faulty, "
                           "replan, got 'nope'"),
    (["--replan-lead", "50"], "option.replan_lead_s: at most 10 s"),
    (["--replan-lead", "0"], "option.replan_lead_s: must be positive"),
])
def test_fly_checks_its_replan_options(tmp_path: Path, flags: list[str], message: str,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """In process (the command line's `main`): the refusal comes before any vehicle or
    socket, and a child Python would add only its start-up."""
    plan_path = tmp_path / "plan.json"
    plan_path.write_text(json.dumps(smooth_plan(line_scenario(2)).to_dict()))
    assert main(["fly", str(plan_path), "--mock", *flags]) == 2
    err = capsys.readouterr().err
    assert message in err, err
