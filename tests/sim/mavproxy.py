"""MAVProxy driven from the tests, shared by the PX4 and ArduCopter personalities' checks."""

from __future__ import annotations

import queue
import shutil
import subprocess
import sys
import threading
from pathlib import Path

from tests.support.waiting import line_with, wait_for

__all__ = ["MavProxy"]


class MavProxy:
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
        return wait_for(line_with(self.lines, text, self.seen), f"MAVProxy to print {text!r}",
                        timeout, detail=lambda: "it printed:\n" + "\n".join(self.seen[-40:]))

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5.0)
