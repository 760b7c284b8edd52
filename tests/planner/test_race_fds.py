"""Two races in one process (`planner.methods.race`, as two Dask tasks in one worker): the
arms of one never hold the pipes of the other."""

from __future__ import annotations

import threading
import time
from typing import Any

from planner.methods.race import race
from tests.support.descriptors import pipes


def test_an_arm_holds_no_pipe_of_another_race() -> None:
    """Race A's arm is still running (its pipe open in this process) when race B forks: B's
    arm finds none of A's pipe descriptors open in its own process (its own write end is
    its only race pipe), and both races end with their results."""
    before = pipes()
    started = threading.Event()
    results: dict[str, Any] = {}

    def slow(send: Any) -> str:
        send("running")
        time.sleep(1.0)
        return "a"

    def run_a() -> None:
        results["a"] = race([("slow", slow)], lambda v: True,
                            progress=lambda _message: started.set())

    thread = threading.Thread(target=run_a)
    thread.start()
    assert started.wait(30.0)
    a_pipes = pipes() - before
    assert a_pipes  # race A's read end, held while its arm runs

    [b] = race([("pipes", lambda _send: pipes())], lambda v: True)
    thread.join(30.0)
    assert b.error is None and a_pipes.isdisjoint(b.value), (a_pipes, b.value)
    assert results["a"][0].value == "a"
