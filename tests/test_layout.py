"""The architecture's import rules, checked by parsing every module's imports.

Imports only run downward (docs/development/architecture.md, README "Architecture"):
- `planner/` never imports `gcs`;
- `gcs/flight/` never imports `gcs.service`, `gcs.api`, `gcs.cli` or `gcs.sim`, and of
  `gcs/fleet/` only the fleet file (fleet commands and provisioning sit above the flight's link
  and procedure); inside it, from the wire up:
  - `link/` (endpoints, signing, telemetry, one vehicle's link, the hub, the setpoints a link
    sends, the station's stalls) imports no other sub-package and no part of `gcs.fleet`;
  - `procedure/` (each autopilot's procedure steps, the geofence upload, the flight context)
    imports only `link/` and the fleet file;
  - then, each importing only those before it (`FLIGHT_LAYERS`): `timeline/` (the setpoint
    stream, the flight clock, the plans flown), `replan/` (in-flight replans, predicted
    motions), `safety/` (monitor, policy, margins, planned landing), `run/` (the executor and
    its parts), and `host/` (the vehicle thread and process, the flight handle), imported by
    none of them; a sub-package not in `FLIGHT_LAYERS` fails;
- `gcs/fleet/` (fleet file, fleet commands, provisioning) imports `gcs.flight` only for the link
  and the procedure (the fleet file, a contract, not at all), and never the service, the API,
  the CLI or the mock;
- `gcs/sim/` (the stand-in for PX4) never imports `gcs.flight` or `gcs.fleet`, so a wire-level
  mistake in our link is not repeated by the mock that should catch it;
- `gcs/service/` never imports `gcs.api`, `gcs.cli` or FastAPI/Starlette, and imports the mock
  (`gcs.sim`) only where it hosts it (`ALLOWED`): `serve --mock N` makes a mock fleet one of
  the service's fleets, started by `service/fleet.py`, configured in the vehicle process by
  `service/vehicle_host.py`, its timings and realism checked by the settings
  (`service/settings.py`). The mock sits below the service (it imports only the bottom layer),
  so these run downward; each module says so in its docstring;
- `gcs/api/` reaches vehicles only through the service: it never imports `gcs.flight`,
  `gcs.sim`, the fleet commands or provisioning (the fleet file's options are a contract, like
  the scenario's, and the API validates them);
- `gcs/export/` (plans written in other tools' formats) and `gcs/show/` (shows from show
  tools, the validation report) import neither the vehicle side (`gcs.flight`, `gcs.fleet`,
  `gcs.sim`) nor the service, the API or the CLI, which call them;
- the shared bottom layer (`gcs/frames.py`, `gcs/wire.py`, `gcs/errors.py`, `gcs/phases.py`:
  the flight's vocabulary, `gcs/documents.py`: the typed shapes of its events, snapshot and
  replan objects; `gcs/autopilot/`: what differs between PX4 and ArduPilot, behind one seam)
  imports no other part of `gcs`; `gcs/geofence.py`
  (the fence's numbers, shared by the flight and the API) and `gcs/replan_request.py` (a replan
  request's body, shared by the API and the CLI) import only that layer.

Only the autopilot modules name an autopilot: no code in the flight (link, procedure,
streaming, monitors, landing, replanning), the fleet commands, the service or the API imports
`gcs.autopilot.px4` or `gcs.autopilot.ardupilot` or has a name that says PX4 or ArduPilot; they
ask the vehicle's `gcs.autopilot.Autopilot` (`NAMES_NO_AUTOPILOT`).

And no module of `planner` or `gcs` imports, directly or through others, a module that imports
it back: the module import graph (imports under ``if TYPE_CHECKING:`` and inside functions
included, relative imports resolved, ``from pkg import module`` as an import of the module)
has no cycle.

One job per module and per function: no module of `planner` or `gcs` over `MODULE_LINES` lines
and no function over `FUNCTION_LINES`, unless its docstring says why in one line,
``Long: <reason>`` (a table or a parser can read best whole); a `Long:` line on a module or
function that is no longer long fails too.

The tests follow one rule of their own: a test module (`tests/**/test_*.py`) imports no other
test module; what tests share lives in a `conftest.py` or a support module (`tests/support/`,
a package's `support.py`).
"""

from __future__ import annotations

import ast
import itertools
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

from tests.paths import ROOT
from tests.support.graphs import a_cycle, cycles, strongly_connected

_ABOVE_GCS = ("gcs.flight", "gcs.fleet", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli")
#: `gcs/flight`'s sub-packages, lowest first: each imports only those before it.
FLIGHT_LAYERS = ("link", "procedure", "timeline", "replan", "safety", "run", "host")
_FLIGHT_UPPER = tuple(f"gcs.flight.{name}" for name in FLIGHT_LAYERS[1:])

#: package (as a path prefix) -> module prefixes it must not import
RULES: dict[str, tuple[str, ...]] = {
    "planner": ("gcs",),
    "gcs/flight": ("gcs.service", "gcs.api", "gcs.cli", "gcs.sim", "gcs.fleet.commands",
                   "gcs.fleet.provision"),
    **{f"gcs/flight/{name}": _FLIGHT_UPPER[n:] for n, name in enumerate(FLIGHT_LAYERS[2:-1], 2)},
    "gcs/flight/link": (*_FLIGHT_UPPER, "gcs.fleet"),
    "gcs/flight/procedure": (*_FLIGHT_UPPER[1:], "gcs.fleet.commands", "gcs.fleet.provision"),
    "gcs/fleet": (*_FLIGHT_UPPER[1:], "gcs.sim", "gcs.service", "gcs.api", "gcs.cli"),
    "gcs/fleet/fleetfile.py": ("gcs.flight",),  # the contract, below every flight part
    "gcs/sim": ("gcs.flight", "gcs.fleet", "gcs.service", "gcs.api", "gcs.cli"),
    "gcs/service": ("gcs.api", "gcs.cli", "fastapi", "starlette", "gcs.sim"),
    "gcs/api": ("gcs.flight", "gcs.sim", "gcs.fleet.commands", "gcs.fleet.provision"),
    "gcs/export": ("gcs.flight", "gcs.fleet", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli",
                   "fastapi", "starlette"),
    "gcs/show": ("gcs.flight", "gcs.fleet", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli",
                 "fastapi", "starlette"),
    "gcs/frames.py": _ABOVE_GCS,
    "gcs/autopilot": _ABOVE_GCS,
    "gcs/wire.py": _ABOVE_GCS,
    "gcs/errors.py": _ABOVE_GCS,
    "gcs/phases.py": _ABOVE_GCS,
    "gcs/documents.py": _ABOVE_GCS,
    "gcs/geofence.py": _ABOVE_GCS,
    "gcs/replan_request.py": _ABOVE_GCS,
}

#: file -> module prefixes it may import although its package's rule forbids them (why: the
#: module docstring)
ALLOWED: dict[str, tuple[str, ...]] = {
    "gcs/service/fleet.py": ("gcs.sim",),
    "gcs/service/vehicle_host.py": ("gcs.sim",),
    "gcs/service/settings.py": ("gcs.sim",),
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
        allowed = ALLOWED.get(str(path.relative_to(ROOT)), ())
        for line, module in imported_modules(path):
            if any(module == f or module.startswith(f + ".") for f in forbidden) and not any(
                    module == a or module.startswith(a + ".") for a in allowed):
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    return bad


@pytest.mark.parametrize("prefix", sorted(RULES))
def test_imports_only_run_downward(prefix: str) -> None:
    assert (ROOT / prefix).exists(), f"{prefix} is gone: move its rule with it"
    assert _violations(prefix, RULES[prefix]) == []


def test_the_flight_package_holds_its_layers() -> None:
    """Every sub-package of `gcs/flight` has its place in `FLIGHT_LAYERS`, so its rule
    exists: a new one is placed there, not left unchecked."""
    found = {p.parent.name for p in (ROOT / "gcs" / "flight").glob("*/__init__.py")}
    assert found == set(FLIGHT_LAYERS)


def imports_of_test_modules(root: Path) -> list[str]:
    """Every import under `root` of a test module (a module named test_*)."""
    found: dict[str, None] = {}
    for path in sorted(root.rglob("*.py")):
        for line, module in imported_modules(path):
            parts = module.split(".")
            tests = [n for n, part in enumerate(parts) if n and part.startswith("test_")]
            if parts[0] == root.name and tests:
                imported = ".".join(parts[:tests[0] + 1])
                found[f"{path.relative_to(root.parent)}:{line} imports {imported}"] = None
    return list(found)


def test_no_test_module_imports_another() -> None:
    """Shared helpers live in conftest.py or a support module, so each test module reads
    alone and can move or go without breaking another."""
    assert imports_of_test_modules(ROOT / "tests") == []


def test_the_checker_sees_a_test_module_imported(tmp_path: Path) -> None:
    root = tmp_path / "tests"
    (root / "api").mkdir(parents=True)
    (root / "api" / "test_a.py").write_text("QUICK = 1\n")
    (root / "api" / "test_b.py").write_text("from tests.api.test_a import QUICK\n")
    (root / "api" / "test_c.py").write_text("from tests.api import test_a\n")
    (root / "api" / "support.py").write_text("import json\n")
    (root / "api" / "test_d.py").write_text("from tests.api.support import json\n")
    assert imports_of_test_modules(root) == ["tests/api/test_b.py:1 imports tests.api.test_a",
                                         "tests/api/test_c.py:1 imports tests.api.test_a"]


@pytest.mark.parametrize("path", sorted(ALLOWED))
def test_every_allowance_is_used(path: str) -> None:
    """An allowance names an import its file still makes, so none outlives its reason."""
    imported = [m for _, m in imported_modules(ROOT / path)]
    for prefix in ALLOWED[path]:
        assert any(m == prefix or m.startswith(prefix + ".") for m in imported), (path, prefix)


def test_the_checker_sees_a_forbidden_import(tmp_path: Path) -> None:
    """The parser finds both import forms, so a violation cannot slip through unseen."""
    module = tmp_path / "m.py"
    module.write_text("import gcs.api.app\nfrom gcs.service import store\n"
                      "def f():\n    from fastapi import FastAPI\n")
    found = [m for _, m in imported_modules(module)]
    assert "gcs.api.app" in found
    assert "gcs.service.store" in found
    assert "fastapi.FastAPI" in found


# ------------------------------------------------------------------------ the autopilot seam

#: Code that must not name an autopilot (it asks the vehicle's `gcs.autopilot.Autopilot`).
NAMES_NO_AUTOPILOT = ("gcs/flight", "gcs/fleet", "gcs/service", "gcs/api")
#: file -> why it may: the service hosts the mock, whose ports are PX4 SITL's.
NAMES_ALLOWED = {"gcs/service/settings.py"}
_AUTOPILOT_NAME = re.compile(r"px4|ardu", re.IGNORECASE)


def autopilot_names(path: Path) -> list[tuple[int, str]]:
    """(line, name) of every identifier, attribute, import or definition in `path` that
    names an autopilot (comments, docstrings and strings are free to)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        names: list[str] = []
        if isinstance(node, ast.Name):
            names = [node.id]
        elif isinstance(node, ast.Attribute):
            names = [node.attr]
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            names = [node.name]
        elif isinstance(node, ast.arg):
            names = [node.arg]
        found.extend((getattr(node, "lineno", 0), n) for n in names if _AUTOPILOT_NAME.search(n))
    return found


@pytest.mark.parametrize("prefix", NAMES_NO_AUTOPILOT)
def test_only_the_autopilot_modules_name_an_autopilot(prefix: str) -> None:
    bad = [f"{path.relative_to(ROOT)}:{line} {name}" for path in _files(prefix)
           if str(path.relative_to(ROOT)) not in NAMES_ALLOWED
           for line, name in autopilot_names(path)]
    assert bad == []


def test_the_name_checker_sees_an_autopilot(tmp_path: Path) -> None:
    """Imports, attributes and names are seen; a docstring or a string is not."""
    module = tmp_path / "m.py"
    module.write_text('''"""PX4 and ArduPilot."""\nfrom gcs.autopilot import px4\n'''
                      "def f(link):\n    return link.mode == px4.HOLD, mavlink.MAV_AUTOPILOT_PX4, "
                      "'ardupilot'\n")
    assert sorted(n for _, n in autopilot_names(module)) == ["MAV_AUTOPILOT_PX4", "px4", "px4"]


# ------------------------------------------------------------------------ import cycles

#: The package trees whose module graph must have no cycle.
CYCLE_TREES = ("planner", "gcs")


def module_name(path: Path, root: Path) -> str:
    """Dotted name of the module in `path` under `root` (a package's ``__init__`` is the
    package)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(name: str, known: set[str]) -> str | None:
    """`name`, or its longest prefix that is a known module (None: outside the graph)."""
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def import_graph(root: Path, trees: Iterable[str] = CYCLE_TREES) -> dict[str, set[str]]:
    """module -> the modules of `trees` it imports (`root` holds the trees' directories)."""
    paths = {module_name(p, root): p for tree in trees for p in sorted((root / tree).rglob("*.py"))}
    known = set(paths)
    graph: dict[str, set[str]] = {}
    for module, path in paths.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base_parts = package.split(".")
                    base_parts = base_parts[:len(base_parts) - (node.level - 1)]
                    base = ".".join([*base_parts, *([node.module] if node.module else [])])
                else:
                    base = node.module or ""
                # `from pkg import module` imports the module; `from pkg import name`, pkg
                names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                         for alias in node.names]
            else:
                continue
            targets.update(t for t in (_resolve(n, known) for n in names) if t is not None)
        targets.discard(module)  # `from . import x` in x's own package __init__ resolves here
        graph[module] = targets
    return graph


def test_no_import_cycle() -> None:
    """Each module can be understood (and imported) before the ones that import it."""
    assert cycles(import_graph(ROOT)) == []


def _package(root: Path, files: Mapping[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_the_cycle_checker_sees_every_import_form(tmp_path: Path) -> None:
    """A cycle closed by a relative import, by ``from pkg import module`` and by an import
    under TYPE_CHECKING is found; an acyclic package is not reported."""
    _package(tmp_path, {
        "gcs/__init__.py": "",
        "gcs/a.py": "from . import b\n",
        "gcs/b.py": "from gcs import c\n",
        "gcs/c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                    "    from gcs.a import Thing\n",
        "gcs/d.py": "from .sub.e import f\nimport gcs.a\n",
        "gcs/sub/__init__.py": "",
        "gcs/sub/e.py": "from ..c import x\n",
        "planner/__init__.py": "",
        "planner/p.py": "import planner.q\n",
        "planner/q.py": "def f():\n    from planner import p\n",
    })
    graph = import_graph(tmp_path)
    assert graph["gcs.a"] == {"gcs.b"}
    assert graph["gcs.c"] == {"gcs.a"}
    assert graph["gcs.d"] == {"gcs.sub.e", "gcs.a"}
    assert graph["gcs.sub.e"] == {"gcs.c"}
    assert strongly_connected(graph) == [["gcs.a", "gcs.b", "gcs.c"], ["planner.p", "planner.q"]]
    assert a_cycle(graph, ["gcs.a", "gcs.b", "gcs.c"]) == ["gcs.a", "gcs.b", "gcs.c", "gcs.a"]
    assert strongly_connected({"x": {"y"}, "y": {"z"}, "z": set()}) == []


# ------------------------------------------------------------- long modules and functions

#: The longest a module (lines) and a function (lines, decorators excluded) may be without a
#: `Long:` line in its docstring.
MODULE_LINES = 400
FUNCTION_LINES = 80
#: The trees held to those lengths.
LENGTH_TREES = ("planner", "gcs")
#: The docstring line that says why a module or function stays long, in one line (a table or
#: a parser can read best whole): ``Long: <reason>``.
LONG_MARK = "Long: "


_Function = ast.FunctionDef | ast.AsyncFunctionDef


def _functions(tree: ast.AST, prefix: str = "") -> Iterable[tuple[str, _Function]]:
    """(dotted name, node) of every function and method in `tree`, nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            name = f"{prefix}{node.name}"
            if not isinstance(node, ast.ClassDef):
                yield name, node
            yield from _functions(node, name + ".")
        else:
            yield from _functions(node, prefix)


def parts(root: Path, trees: Iterable[str] = LENGTH_TREES) -> Iterable[tuple[str, int, str]]:
    """(name, lines, docstring) of every module and function under `root`'s `trees`: a module
    by its path, a function by ``path::name`` (a method or a nested function:
    ``path::outer.name``); "" for no docstring."""
    for tree in trees:
        for path in sorted((root / tree).rglob("*.py")):
            rel = str(path.relative_to(root))
            text = path.read_text()
            module = ast.parse(text, filename=rel)
            yield rel, len(text.splitlines()), ast.get_docstring(module) or ""
            for name, node in _functions(module):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                yield f"{rel}::{name}", lines, ast.get_docstring(node) or ""


def long_reason(docstring: str) -> str | None:
    """The reason the docstring's `LONG_MARK` line gives, with any lines that continue it
    (one-line reasons have none), or None without such a line."""
    lines = docstring.splitlines()
    for n, line in enumerate(lines):
        if line.startswith(LONG_MARK):
            paragraph = itertools.takewhile(str.strip, lines[n + 1:])
            return "\n".join([line.removeprefix(LONG_MARK), *paragraph])
    return None


def _limit(name: str) -> int:
    return FUNCTION_LINES if "::" in name else MODULE_LINES


def long_parts(root: Path, trees: Iterable[str] = LENGTH_TREES) -> dict[str, int]:
    """Every module over MODULE_LINES lines and function over FUNCTION_LINES under `root`'s
    `trees`, with its length."""
    return {name: lines for name, lines, _ in parts(root, trees) if lines > _limit(name)}


def long_reasons(root: Path, trees: Iterable[str] = LENGTH_TREES) -> dict[str, str]:
    """The reason of every module and function under `root`'s `trees` that gives one."""
    return {name: reason for name, _, doc in parts(root, trees)
            if (reason := long_reason(doc)) is not None}


def unexplained(root: Path, trees: Iterable[str] = LENGTH_TREES) -> dict[str, int]:
    """The long modules and functions (with their lengths) that give no reason."""
    reasons = long_reasons(root, trees)
    return {name: n for name, n in long_parts(root, trees).items() if name not in reasons}


def stale(root: Path, trees: Iterable[str] = LENGTH_TREES) -> list[str]:
    """The modules and functions that give a reason but are not long."""
    return sorted(set(long_reasons(root, trees)) - set(long_parts(root, trees)))


def test_long_modules_and_functions_say_why() -> None:
    """One job per module and per function: a long one is split, or its docstring says why
    not."""
    assert unexplained(ROOT) == {}, (
        f"over {MODULE_LINES} lines (a module) or {FUNCTION_LINES} (a function): split it by "
        f"concept, or add a one-line `{LONG_MARK}<reason>` to its docstring")


def test_every_long_line_is_on_a_long_part() -> None:
    """A `Long:` line goes once its module or function is short, so no reason outlives it."""
    assert stale(ROOT) == [], (
        f"no longer over {MODULE_LINES} lines (a module) or {FUNCTION_LINES} (a function): "
        f"remove the `{LONG_MARK.strip()}` line from its docstring")


def test_every_long_reason_is_one_line() -> None:
    """The reason is one line, so it stays a reason and not a second docstring."""
    wrapped = {name: reason for name, reason in long_reasons(ROOT).items() if "\n" in reason}
    assert wrapped == {}, f"shorten each `{LONG_MARK.strip()}` reason to one line"


def _long_function(name: str, indent: str = "", doc: str = "") -> str:
    """A function of FUNCTION_LINES + 1 lines (its def and FUNCTION_LINES statements), the
    first of them `doc` as its docstring when given."""
    body = [f"{indent}    x{n} = {n}" for n in range(FUNCTION_LINES)]
    if doc:
        body[0] = f'{indent}    """{doc}"""'
    return "\n".join([f"{indent}def {name}():", *body]) + "\n"


def test_the_length_checker_sees_modules_methods_and_nested_functions(tmp_path: Path) -> None:
    _package(tmp_path, {
        "gcs/short.py": "def f():\n    return 1\n",
        "gcs/long.py": "\n" * MODULE_LINES + "X = 1\n",
        "gcs/funcs.py": "class C:\n" + _long_function("m", "    ") + "def outer():\n"
                        + _long_function("inner", "    ") + "    return inner\n",
    })
    assert long_parts(tmp_path, ("gcs",)) == {"gcs/long.py": MODULE_LINES + 1,
                                              "gcs/funcs.py::C.m": FUNCTION_LINES + 1,
                                              "gcs/funcs.py::outer": FUNCTION_LINES + 3,
                                              "gcs/funcs.py::outer.inner": FUNCTION_LINES + 1}


def test_the_length_checker_reads_reasons_from_docstrings(tmp_path: Path) -> None:
    """A module's and a method's `Long:` lines are found wherever they stand in the docstring
    (right under a line of text, or a paragraph of their own); a reason wrapped onto a second
    line comes with it; a short function's is found too (to be reported as stale); a comment
    or a string that is not the docstring gives no reason."""
    _package(tmp_path, {
        "gcs/long.py": '"""A table.\nLong: one table, read whole.\n"""\n'
                       + "\n" * MODULE_LINES,
        "gcs/funcs.py": "class C:\n"
                        + _long_function("m", "    ", "A parser.\n\n        Long: one parser")
                        + 'def short():\n    """Short.\n\n    Long: a stale reason\n'
                        + '    wrapped."""\n'
                        + "def plain():\n    # Long: a comment\n    return 'Long: a string'\n",
    })
    assert long_reasons(tmp_path, ("gcs",)) == {"gcs/long.py": "one table, read whole.",
                                                "gcs/funcs.py::C.m": "one parser",
                                                "gcs/funcs.py::short": "a stale reason\nwrapped."}
    assert unexplained(tmp_path, ("gcs",)) == {}
    assert stale(tmp_path, ("gcs",)) == ["gcs/funcs.py::short"]


def test_the_length_checker_sees_a_long_part_without_a_reason(tmp_path: Path) -> None:
    _package(tmp_path, {
        "gcs/long.py": '"""A module that says nothing of its length."""\n' + "\n" * MODULE_LINES,
        "gcs/funcs.py": _long_function("f", doc="A function that says nothing either."),
    })
    assert unexplained(tmp_path, ("gcs",)) == {"gcs/long.py": MODULE_LINES + 1,
                                               "gcs/funcs.py::f": FUNCTION_LINES + 1}
