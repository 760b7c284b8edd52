"""Tests wait through one helper (`tests/support/waiting.py`), never a loop of their own.

A `while` loop that sleeps, or a `for` loop that sleeps and leaves early, is a hand-written
wait: bounded by nothing but pytest's timeout, or by a deadline of its own and a failure that
names nothing. `until`, `wait_for` and `reached` bound every wait and say what was awaited;
`every` runs a sampler or a feed until cancelled. Only `tests/support/` holds such loops, and
`ALLOWED` the few elsewhere that are not waits, each with the reason.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

from tests.paths import ROOT

TESTS = ROOT / "tests"
SUPPORT = TESTS / "support"

#: (file under the project, enclosing function's qualified name) -> why its loop stays.
ALLOWED = {
    ("tests/flight/fakes.py", "FakeLink.wait_for"):
        "a fake of `VehicleLink.wait_for`: it answers False on timeout, as the link does",
}


def _calls_sleep(node: ast.AST) -> bool:
    """`node` calls `sleep` (`time.sleep`, `asyncio.sleep` or an imported `sleep`)."""
    for call in ast.walk(node):
        if isinstance(call, ast.Call):
            func = call.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if name == "sleep":
                return True
    return False


def _leaves_early(loop: ast.For | ast.AsyncFor) -> bool:
    """`loop`'s body breaks out of it or returns (a break of a nested loop does not count)."""
    def exits(node: ast.AST, nested: bool) -> bool:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            return False
        if isinstance(node, ast.Return) or (isinstance(node, ast.Break) and not nested):
            return True
        inner = nested or isinstance(node, (ast.For, ast.AsyncFor, ast.While))
        return any(exits(child, inner) for child in ast.iter_child_nodes(node))

    return any(exits(statement, False) for statement in loop.body)


def _polling_loops(tree: ast.Module) -> Iterator[tuple[int, str]]:
    """(line, enclosing function's qualified name) of each hand-written wait in `tree`."""
    def visit(node: ast.AST, scope: tuple[str, ...]) -> Iterator[tuple[int, str]]:
        for child in ast.iter_child_nodes(node):
            inner = scope
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                inner = (*scope, child.name)
            loop = isinstance(child, ast.While) or (
                isinstance(child, (ast.For, ast.AsyncFor)) and _leaves_early(child))
            if loop and _calls_sleep(child):
                yield child.lineno, ".".join(scope) or "<module>"
            yield from visit(child, inner)
    return visit(tree, ())


def _found(paths: list[Path]) -> list[tuple[str, int, str]]:
    """Every hand-written wait in `paths`: (file, line, function)."""
    found = []
    for path in paths:
        for line, where in _polling_loops(ast.parse(path.read_text(), str(path))):
            found.append((path.relative_to(ROOT).as_posix(), line, where))
    return found


def test_no_test_waits_in_a_loop_of_its_own() -> None:
    paths = [p for p in sorted(TESTS.rglob("*.py")) if SUPPORT not in p.parents]
    found = _found(paths)
    loops = [f"{file}:{line} in {where}" for file, line, where in found
             if (file, where) not in ALLOWED]
    assert not loops, ("wait with tests.support.waiting (until, wait_for, reached) or run "
                       "a periodic action with `every`:\n" + "\n".join(loops))
    # every exception is still needed: a stale entry would hide the next loop written there
    used = {(file, where) for file, _line, where in found}
    assert set(ALLOWED) <= used, set(ALLOWED) - used


def test_the_check_finds_each_kind_of_hand_written_wait(tmp_path: Path) -> None:
    sample = tmp_path / "sample.py"
    sample.write_text(
        "import asyncio, time\n"
        "async def polls(flight):\n"
        "    while flight.busy:\n"
        "        await asyncio.sleep(0.02)\n"
        "class Poller:\n"
        "    def bounded(self, ready):\n"
        "        for _ in range(100):\n"
        "            if ready():\n"
        "                break\n"
        "            time.sleep(0.05)\n"
        "def samples(out):\n"
        "    for _ in range(10):\n"  # a fixed number of samples: not a wait
        "        time.sleep(0.1)\n"
        "        out.append(1)\n"
        "    while out:\n"  # a loop that does not sleep: not a wait
        "        out.pop()\n")
    tree = ast.parse(sample.read_text())
    assert list(_polling_loops(tree)) == [(3, "polls"), (7, "Poller.bounded")]
