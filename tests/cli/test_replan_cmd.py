"""`fleetplan fly --control PATH`'s socket and `fleetplan replan PATH ...`: the socket's mode
and lifetime, what reaches the flight, every refusal naming its field, the command's exit
status. The flight behind the socket here records what it is asked and answers as
`FlightHandle` does (its replan itself is flown in tests/cli/test_replan_flight.py)."""

from __future__ import annotations

import asyncio
import json
import os
import socket
import stat
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from gcs.cli.control import ControlServer, request
from gcs.errors import StateConflict
from planner.errors import ScenarioError

pytestmark = pytest.mark.timeout(60)


class Recording:
    """A flight behind the socket: records each call; `refuse` makes the next one raise."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.refuse: Exception | None = None

    def _next(self, *call: Any) -> None:
        self.calls.append(call)
        if self.refuse is not None:
            error, self.refuse = self.refuse, None
            raise error

    async def replan(self, goals: dict[str, list[float]] | None, drop: list[str],
                     drop_action: str, reason: str) -> dict[str, Any]:
        self._next("replan", goals, drop, drop_action, reason)
        return {"id": len(self.calls), "status": "planning", "requested_at": 2.0,
                "switch_time": 3.0, "lead_s": 1.0, "planning_s": None, "goals": goals or {},
                "drop": drop, "drop_action": drop_action, "reason": reason}

    async def pause(self) -> float:
        self._next("pause")
        return 1.5

    async def resume(self) -> float:
        self._next("resume")
        return 1.5

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        self._next("abort", action, reason)


class Served:
    """A ControlServer on its own thread's loop (as `fleetplan fly` runs one)."""

    def __init__(self, path: Path, vehicles: int = 4) -> None:
        self.flight = Recording()
        self.server = ControlServer(path, self.flight, vehicles)
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()

    def run(self, coroutine: Any) -> Any:
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(timeout=20)

    def close(self) -> None:
        self.run(self.server.close())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(timeout=10)
        self.loop.close()


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    s = Served(tmp_path / "fly.sock")
    s.run(s.server.start())
    yield s
    s.close()


def ask(path: Path, document: Any) -> dict[str, Any]:
    return asyncio.run(request(path, document))


def ask_raw(path: Path, data: bytes) -> dict[str, Any]:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as client:
        client.settimeout(20)
        client.connect(str(path))
        client.sendall(data)
        client.shutdown(socket.SHUT_WR)
        answer = b""
        while chunk := client.recv(65536):
            answer += chunk
    return json.loads(answer)


def test_the_socket_is_the_owners_only_and_removed_at_the_end(tmp_path: Path) -> None:
    s = Served(tmp_path / "fly.sock")
    s.run(s.server.start())
    mode = os.stat(s.server.path).st_mode
    assert stat.S_ISSOCK(mode) and stat.S_IMODE(mode) == 0o600
    s.close()
    assert not s.server.path.exists()


def test_a_replan_reaches_the_flight_and_its_object_comes_back(served: Served) -> None:
    answer = ask(served.server.path, {"command": "replan", "goals": {"uav2": [1, 2.5, 3]},
                                      "drop": ["uav3"], "drop_action": "hold"})
    assert answer["ok"] is True
    assert answer["replan"]["status"] == "planning" and answer["replan"]["drop"] == ["uav3"]
    assert served.flight.calls == [("replan", {"uav2": [1.0, 2.5, 3.0]}, ["uav3"], "hold",
                                    "operator (control socket)")]
    # drop_action defaults to land; a replan of goals alone passes no drop
    ask(served.server.path, {"command": "replan", "drop": ["uav1"]})
    ask(served.server.path, {"command": "replan", "goals": {"uav1": [0, 0, 1]}})
    assert served.flight.calls[1:] == [
        ("replan", None, ["uav1"], "land", "operator (control socket)"),
        ("replan", {"uav1": [0.0, 0.0, 1.0]}, [], "land", "operator (control socket)")]


def test_pause_resume_and_abort(served: Served) -> None:
    assert ask(served.server.path, {"command": "pause"}) == {"ok": True, "flight_time": 1.5}
    assert ask(served.server.path, {"command": "resume"}) == {"ok": True, "flight_time": 1.5}
    assert ask(served.server.path, {"command": "abort", "action": "hold"}) == {"ok": True}
    assert [c[:2] for c in served.flight.calls] == [("pause",), ("resume",),
                                                     ("abort", "hold")]


def test_the_flights_refusals_cross_with_their_field(served: Served) -> None:
    served.flight.refuse = StateConflict("replan", "a replan is already running")
    answer = ask(served.server.path, {"command": "replan", "drop": ["uav3"]})
    assert answer == {"ok": False, "error": {"type": "StateConflict", "field": "replan",
                                             "reason": "a replan is already running"}}
    served.flight.refuse = ScenarioError("goals.uav2", "lies inside obstacle 'tower'")
    answer = ask(served.server.path, {"command": "replan", "goals": {"uav2": [1, 1, 1]}})
    assert answer["error"] == {"type": "ScenarioError", "field": "goals.uav2",
                               "reason": "lies inside obstacle 'tower'"}


@pytest.mark.parametrize(
    ("document", "field", "reason"),
    [
        ({"command": "land"}, "command", "must be one of replan, pause, resume, abort"),
        ({"goals": {"a": [1, 2, 3]}}, "command", "got None"),
        ([1, 2], "body", "must be a JSON object"),
        ({"command": "replan"}, "goals", "give new goals, vehicles to drop, or both"),
        ({"command": "replan", "goals": {"a": [1, 2]}}, "goals.a", "at least 3 items"),
        ({"command": "replan", "drop": ["a", "a"]}, "drop[1]", "'a' is listed twice"),
        ({"command": "replan", "drop": ["a", "b", "c", "d", "e"]}, "drop",
         "5 entries exceed the plan's 4 vehicles"),
        ({"command": "replan", "drop": ["a"], "drop_action": "rtl"}, "drop_action", "'land'"),
        ({"command": "replan", "drop": ["a"], "why": "x"}, "why", "Extra inputs"),
        ({"command": "pause", "at": 3}, "at", "is not a field of this command"),
        ({"command": "abort", "action": "rtl"}, "action", "must be one of hold, land"),
    ],
)
def test_bad_requests_name_the_field_and_reach_nothing(
    served: Served, document: Any, field: str, reason: str
) -> None:
    answer = ask(served.server.path, document)
    assert answer["ok"] is False and answer["error"]["field"] == field, answer
    assert reason in answer["error"]["reason"], answer
    assert served.flight.calls == []


@pytest.mark.parametrize("data", [b"not json\n", b"\n", b'{"command": "replan", "goals": '
                                  b'{"a": [1, NaN, 2]}}\n'])
def test_malformed_lines_are_refused(served: Served, data: bytes) -> None:
    answer = ask_raw(served.server.path, data)
    assert answer["ok"] is False and answer["error"]["field"] in ("body", "goals.a[1]"), answer
    assert served.flight.calls == []


def test_a_stale_socket_is_replaced_and_anything_else_is_left_alone(tmp_path: Path) -> None:
    path = tmp_path / "fly.sock"
    stale = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    stale.bind(str(path))  # what a killed run leaves: a socket nobody listens on
    stale.close()
    s = Served(path)
    s.run(s.server.start())
    assert ask(path, {"command": "pause"})["ok"] is True
    # A second flight on the same path is refused while the first listens.
    other = Served(path)
    with pytest.raises(OSError, match="another flight's control socket listens there"):
        other.run(other.server.start())
    other.close()
    assert path.exists()  # the first one's socket stays
    s.close()
    regular = tmp_path / "notes.txt"
    regular.write_text("keep me")
    third = Served(regular)
    with pytest.raises(OSError, match="exists and is not a socket"):
        third.run(third.server.start())
    third.close()
    assert regular.read_text() == "keep me"


def _replan_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "gcs.cli.main", "replan", *args],
                          capture_output=True, text=True, timeout=60)


def test_the_command_sends_goals_and_drops_and_prints_the_replan(
    served: Served, tmp_path: Path
) -> None:
    goals = tmp_path / "goals.json"
    goals.write_text(json.dumps({"uav1": [0.5, 1, 2], "uav2": [9, 9, 9]}))
    done = _replan_cli(str(served.server.path), "--goals", str(goals), "--goal",
                       "uav2=1,2.5,3", "--drop", "uav3", "--drop-action", "hold")
    assert done.returncode == 0, done.stderr
    printed = json.loads(done.stdout)
    assert printed["status"] == "planning" and printed["switch_time"] == 3.0
    # --goal entries are added to the file's (and win over them)
    assert served.flight.calls == [("replan", {"uav1": [0.5, 1.0, 2.0], "uav2": [1.0, 2.5, 3.0]},
                                    ["uav3"], "hold", "operator (control socket)")]


def test_a_refusal_exits_1_naming_the_field(served: Served) -> None:
    served.flight.refuse = ScenarioError("goals.uav2", "lies outside the workspace on axis x")
    done = _replan_cli(str(served.server.path), "--goal", "uav2=99,0,1")
    assert done.returncode == 1
    assert "refused (ScenarioError): goals.uav2: lies outside the workspace on axis x" \
        in done.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--goal", "uav2=1,2"], "--goal 'uav2=1,2': expected ID=X,Y,Z"),
        (["--goal", "uav2=1,x,2"], "X, Y and Z must be numbers"),
        (["--goal", "uav2=1,inf,2"], "X, Y and Z must be finite"),
        (["--goal", "a=1,2,3", "--goal", "a=1,2,4"], "--goal a: given twice"),
        (["--goal", "a=1,2,3", "--drop", "a"], "goals.a: 'a' is dropped"),
        (["--drop", "a", "--drop", "a"], "drop[1]: 'a' is listed twice"),
        ([], "goals: give new goals, vehicles to drop, or both"),
    ],
)
def test_bad_arguments_exit_2_before_anything_is_sent(
    served: Served, args: list[str], message: str
) -> None:
    done = _replan_cli(str(served.server.path), *args)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert served.flight.calls == []


def test_a_bad_goals_file_and_no_flight_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "goals.json"
    bad.write_text("[1, 2, 3]")
    done = _replan_cli(str(tmp_path / "fly.sock"), "--goals", str(bad))
    assert done.returncode == 2 and "must hold a JSON object" in done.stderr
    bad.write_text('{"uav2": [1, 2]}')
    done = _replan_cli(str(tmp_path / "fly.sock"), "--goals", str(bad))
    assert done.returncode == 2 and "goals.uav2: List should have at least 3 items" \
        in done.stderr
    done = _replan_cli(str(tmp_path / "fly.sock"), "--drop", "uav3")
    assert done.returncode == 2 and f"no flight answers at {tmp_path / 'fly.sock'}" \
        in done.stderr
