"""No test reads private state or imports a private name: a test pinned to a private name breaks
on every rename and hides what the code promises. Where a test needs a seam, the code has a
public one (`gcs.flight.link.interface.Link` for a link in memory, `Scenario.with_fixed_set`).

Checked by parsing every Python file under `tests/`: an attribute whose name starts with one
underscore (not a dunder) on anything but the file's own ``self`` or ``cls``; an import of such
a name; such a name given as a string to ``setattr``, ``getattr``, ``monkeypatch.setattr``
or ``mock.patch``, alone or as the last part of a dotted path; and an item of another object's
``__dict__`` (what a cached property keeps there is its own business).
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

TESTS = Path(__file__).resolve().parent

#: A dotted Python path (what ``monkeypatch.setattr("pkg.mod.name", ...)`` takes).
DOTTED = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)+")
#: The calls that name an attribute by a string: the builtins, ``monkeypatch.setattr`` and
#: ``delattr``, ``mock.patch`` and ``mock.patch.object``.
NAMING_CALLS = frozenset({"setattr", "getattr", "hasattr", "delattr", "patch", "object"})


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _own(node: ast.expr) -> bool:
    """`node` is the file's own ``self`` or ``cls``."""
    return isinstance(node, ast.Name) and node.id in ("self", "cls")


def _string_names(call: ast.Call) -> Iterator[str]:
    """The names a call that names an attribute is given as strings: a lone name or a
    dotted path's last part."""
    func = call.func
    called = func.id if isinstance(func, ast.Name) else getattr(func, "attr", None)
    if called not in NAMING_CALLS:
        return
    for arg in call.args[:2]:
        if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
            text = arg.value
            if text.isidentifier():
                yield text
            elif DOTTED.fullmatch(text):
                yield text.rsplit(".", 1)[1]


def _reaches_in(node: ast.AST) -> bool:
    """`node` reads or writes another object's private attribute or its ``__dict__``."""
    if isinstance(node, ast.Attribute):
        return _private(node.attr) and not _own(node.value)
    return (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute)
            and node.value.attr == "__dict__" and not _own(node.value.value))


def private_uses(source: str, filename: str = "<test>") -> list[str]:
    """Every private name `source` reaches into, as "line: what", in line order."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source, filename)):
        if _reaches_in(node):
            found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.ImportFrom):
            found += [(node.lineno, f"import {a.name} from {node.module}")
                      for a in node.names if _private(a.name)]
        elif isinstance(node, ast.Call):
            found += [(node.lineno, f"{ast.unparse(node.func)}(... {name!r} ...)")
                      for name in _string_names(node) if _private(name)]
    return [f"{line}: {what}" for line, what in sorted(found)]


def test_the_check_finds_each_kind_of_private_use() -> None:
    source = """
from gcs.flight.run import executor
from planner.scp.separation import _pair_chunks
flight._task.cancel()
monkeypatch.setattr(separation, "_pair_chunks", None)
monkeypatch.setattr("planner.scp.separation._pair_chunks", None)
getattr(flight, "_replanner")
scenario.__dict__["fixed_set"] = fixed
"""
    assert [use.split(":")[0] for use in private_uses(source)] == ["3", "4", "5", "6", "7", "8"]


def test_the_check_leaves_public_names_and_a_class_of_its_own_alone() -> None:
    source = """
from tests.support.shows import ground_show as _show
class Fake:
    def __init__(self):
        self._sent = []
    def sent(self):
        return self._sent
msg.__class__
record.get("_h_acc")
monkeypatch.setattr(separation, "all_pairs", None)
page.evaluate("() => document.getElementById('plot')._fullData")
"""
    assert private_uses(source) == []


def test_no_test_reaches_into_a_private_name() -> None:
    found = {str(path.relative_to(TESTS.parent)): uses
             for path in sorted(TESTS.rglob("*.py"))
             if (uses := private_uses(path.read_text(encoding="utf-8"), str(path)))}
    assert found == {}
