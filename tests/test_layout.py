"""The architecture's import rules, checked by parsing every module's imports.

Imports only run downward (DESIGN.md, README "Architecture"):
- `planner/` never imports `gcs`;
- `gcs/flight/` never imports `gcs.service`, `gcs.api`, `gcs.cli` or `gcs.sim`;
- `gcs/sim/` (the stand-in for PX4) never imports `gcs.flight`, so a wire-level mistake in our
  link is not repeated by the mock that should catch it;
- `gcs/service/` never imports `gcs.api`, `gcs.cli` or FastAPI/Starlette;
- the shared bottom layer (`gcs/frames.py`, `gcs/px4.py`, `gcs/wire.py`, `gcs/errors.py`)
  imports no other part of `gcs`.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.paths import ROOT

#: package (as a path prefix) -> module prefixes it must not import
RULES: dict[str, tuple[str, ...]] = {
    "planner": ("gcs",),
    "gcs/flight": ("gcs.service", "gcs.api", "gcs.cli", "gcs.sim"),
    "gcs/sim": ("gcs.flight", "gcs.service", "gcs.api", "gcs.cli"),
    "gcs/service": ("gcs.api", "gcs.cli", "fastapi", "starlette"),
    "gcs/frames.py": ("gcs.flight", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli"),
    "gcs/px4.py": ("gcs.flight", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli"),
    "gcs/wire.py": ("gcs.flight", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli"),
    "gcs/errors.py": ("gcs.flight", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli"),
}


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, dotted module) for every import in `path`, including `from x import y` as x.y."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
            found.extend((node.lineno, f"{node.module}.{alias.name}") for alias in node.names)
    return found


def _files(prefix: str) -> list[Path]:
    target = ROOT / prefix
    return [target] if target.suffix == ".py" else sorted(target.rglob("*.py"))


def _violations(prefix: str, forbidden: tuple[str, ...]) -> list[str]:
    bad = []
    for path in _files(prefix):
        for line, module in imported_modules(path):
            if any(module == f or module.startswith(f + ".") for f in forbidden):
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    return bad


@pytest.mark.parametrize("prefix", sorted(RULES))
def test_imports_only_run_downward(prefix: str) -> None:
    if not (ROOT / prefix).exists():
        pytest.skip(f"{prefix} does not exist")
    assert _violations(prefix, RULES[prefix]) == []


def test_the_checker_sees_a_forbidden_import(tmp_path: Path) -> None:
    """The parser finds both import forms, so a violation cannot slip through unseen."""
    module = tmp_path / "m.py"
    module.write_text("import gcs.api.app\nfrom gcs.service import store\n"
                      "def f():\n    from fastapi import FastAPI\n")
    found = [m for _, m in imported_modules(module)]
    assert "gcs.api.app" in found
    assert "gcs.service.store" in found
    assert "fastapi.FastAPI" in found
