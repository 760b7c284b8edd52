"""MAVProxy (a third-party ground station, from PyPI in the test extras) talks to the mock as to
PX4: it connects, fetches every parameter, lists the empty mission and fence, sets a
parameter, arms and takes off with `takeoff 2`. Driven through its stdin without a display,
each step waiting for MAVProxy's own answer, every wait bounded."""

from __future__ import annotations

import asyncio
import queue
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from gcs.autopilot import px4
from gcs.sim import MockFleet
from gcs.sim.paramdefs import PX4_PARAMS
from tests.flight.support import mock_ports

pytest.importorskip("MAVProxy", reason="MAVProxy is in the test extras: make install")

pytestmark = pytest.mark.timeout(120)


class _MavProxy:
    """mavproxy.py as a child process: commands on stdin, its output lines in a queue."""

    def __init__(self, master: str, workdir: Path) -> None:
        exe = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent))
        assert exe is not None, "mavproxy.py not installed beside this Python"
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self.proc = subprocess.Popen(
            [sys.executable, "-u", exe, f"--master={master}", "--no-state"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, cwd=workdir, env={"PATH": "/usr/bin:/bin", "HOME": str(workdir)})
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def send(self, command: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def expect(self, text: str, timeout: float) -> str:
        """The first output line (from now on) containing `text`."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"MAVProxy never printed {text!r}; it printed:\n"
                                     + "\n".join(self.seen[-40:]))
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                continue
            self.seen.append(line)
            if text in line:
                return line

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5.0)


def test_mavproxy_fetches_parameters_lists_missions_and_takes_off(tmp_path: Path) -> None:
    async def main() -> None:
        ports = mock_ports(1)
        async with MockFleet(1, settle_time=0.5, **ports) as mock:
            v = mock.vehicles[0]
            proxy = _MavProxy(f"udpin:127.0.0.1:{v.gcs_port}", tmp_path)
            try:
                await asyncio.to_thread(_connect_and_list, proxy)
                proxy.send("param set MIS_TAKEOFF_ALT 2")
                await _until(lambda: v.config.takeoff_altitude == 2.0, "MIS_TAKEOFF_ALT set")
                proxy.send("arm throttle")
                await asyncio.to_thread(proxy.expect, "COMPONENT_ARM_DISARM: ACCEPTED", 30.0)
                await _until(lambda: v.armed, "armed")
                proxy.send("takeoff 2")
                await asyncio.to_thread(proxy.expect, "NAV_TAKEOFF: ACCEPTED", 30.0)
                # MAVProxy's takeoff 2 (param7 = 2 m AMSL, as MAVProxy sends it) is raised to
                # MIS_TAKEOFF_ALT, which MAVProxy set to 2 m: the vehicle holds 2 m up
                await _until(lambda: v.mode == px4.HOLD and v.in_air, "holding after takeoff")
                assert v.armed and -v.position_ned[2] == pytest.approx(2.0, abs=0.2)
            finally:
                proxy.close()

    def _connect_and_list(proxy: _MavProxy) -> None:
        proxy.expect("online system 1", 30.0)
        proxy.send("param fetch")
        proxy.expect(f"Received {len(PX4_PARAMS)} parameters", 30.0)
        proxy.send("wp list")
        proxy.expect("Requesting 0 waypoints", 30.0)
        proxy.send("fence list")
        proxy.expect("Requesting 0 fence items", 30.0)

    async def _until(condition: Callable[[], bool], what: str) -> None:
        deadline = time.monotonic() + 30.0  # bound: each step, on a busy machine
        while not condition():
            assert time.monotonic() < deadline, f"never: {what}"
            await asyncio.sleep(0.05)

    asyncio.run(main())
