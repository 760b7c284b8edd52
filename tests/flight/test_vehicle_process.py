"""`VehicleProcess`: calls reach the host in another process and come back (errors as they
were raised), notices arrive in order, a dead child fails what waits on it, and a child whose
caller is gone closes its host (the service's lands a flight) before it exits."""

from __future__ import annotations

import asyncio
import functools
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gcs.errors import GcsError, StateConflict, VehicleLoopStopped
from gcs.flight.host.vehicle_process import VehicleProcess
from tests.flight.process_host import EchoHost
from tests.paths import ROOT
from tests.support.waiting import wait_for

pytestmark = pytest.mark.timeout(120)


def _process(tmp_path: Path, notices: list[tuple[str, Any]] | None = None) -> VehicleProcess:
    return VehicleProcess(functools.partial(EchoHost, closed_mark=str(tmp_path / "closed")),
                          name="fleetplan-test-process",
                          on_notice=None if notices is None else
                          lambda kind, data: notices.append((kind, data)))


def test_calls_errors_and_notices_cross_the_process_boundary(tmp_path: Path) -> None:
    notices: list[tuple[str, Any]] = []

    async def main() -> None:
        process = _process(tmp_path, notices)
        await process.start()
        try:
            assert await process.call("pid") == process.pid != os.getpid()
            assert await process.call("add", 2, 3, times=4) == 20
            with pytest.raises(StateConflict) as refused:
                await process.call("refuse")
            assert (refused.value.field, refused.value.reason) == ("fleet", "no")
            for private in ("_closed_mark", "__init__", "missing"):
                with pytest.raises(GcsError, match="no host method"):
                    await process.call(private)
            assert await process.call("announce", 50) == 50
            await asyncio.sleep(0.2)  # the notices were sent before the answer
        finally:
            await process.stop()

    asyncio.run(main())
    ticks = [data["i"] for kind, data in notices if kind == "tick"]
    assert ticks == list(range(50))
    assert (tmp_path / "closed").exists()  # stop closed the host


def test_a_killed_child_fails_the_waiting_calls_and_says_so(tmp_path: Path) -> None:
    notices: list[tuple[str, Any]] = []

    async def main() -> None:
        process = _process(tmp_path, notices)
        await process.start()
        waiting = asyncio.ensure_future(process.call("wait"))
        await asyncio.sleep(0.1)
        assert process.pid is not None
        os.kill(process.pid, signal.SIGKILL)
        with pytest.raises(VehicleLoopStopped, match="ended"):
            await asyncio.wait_for(waiting, 30)
        assert not process.alive
        with pytest.raises(VehicleLoopStopped):
            await process.call("pid")
        await process.stop()

    asyncio.run(main())
    assert [kind for kind, _ in notices] == ["ended"]
    assert not (tmp_path / "closed").exists()  # SIGKILL: nothing ran


def test_a_child_whose_caller_dies_closes_its_host(tmp_path: Path) -> None:
    """The caller's process is killed outright: the child sees its pipe close, closes the host
    (landing what flies, in the service) and exits."""
    script = (
        "import asyncio, functools, sys, time\n"
        "from gcs.flight.host.vehicle_process import VehicleProcess\n"
        "from tests.flight.process_host import EchoHost\n"
        "async def main():\n"
        "    p = VehicleProcess(functools.partial(EchoHost, closed_mark=sys.argv[1]))\n"
        "    await p.start()\n"
        "    print(p.pid, flush=True)\n"
        "    time.sleep(3600)\n"
        "if __name__ == '__main__':\n"
        "    asyncio.run(main())\n")
    mark = tmp_path / "closed"
    caller = subprocess.Popen([sys.executable, "-c", script, str(mark)], cwd=ROOT,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert caller.stdout is not None
        child = int(caller.stdout.readline())
        caller.kill()
        caller.wait(30)
        wait_for(mark.exists, "the orphaned child to close its host", timeout=60.0)
        assert mark.read_text() == str(child)
    finally:
        if caller.poll() is None:
            caller.kill()
