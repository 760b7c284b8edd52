"""The architecture's import rules, checked by parsing every module's imports.

Imports only run downward (docs/development/architecture.md, README "Architecture"):
- `planner/` never imports `gcs`;
- `gcs/flight/` never imports `gcs.service`, `gcs.api`, `gcs.cli` or `gcs.sim`, and of
  `gcs/fleet/` only the fleet file (fleet commands and provisioning sit above the flight's link
  and procedure); inside it, from the wire up:
  - `link/` (endpoints, signing, telemetry, one vehicle's link, the hub, the setpoints a link
    sends, the station's stalls) imports no other sub-package and no part of `gcs.fleet`;
  - `procedure/` (the PX4 procedure, the geofence upload) imports only `link/` and the fleet
    file;
  - `host/` (the vehicle thread and process, the flight handle) is imported by none of them;
- `gcs/fleet/` (fleet file, fleet commands, provisioning) imports `gcs.flight` only for the link
  and the procedure, and never the service, the API, the CLI or the mock;
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
and no function over `FUNCTION_LINES`, unless `LONG` names it with a one-line reason; an entry
whose module or function is no longer long fails too.

The tests follow one rule of their own: a test module (`tests/**/test_*.py`) imports no other
test module; what tests share lives in a `conftest.py` or a support module (`tests/support/`,
a package's `support.py`).
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

from tests.paths import ROOT
from tests.support.graphs import a_cycle, cycles, strongly_connected

_ABOVE_GCS = ("gcs.flight", "gcs.fleet", "gcs.sim", "gcs.service", "gcs.api", "gcs.cli")
_FLIGHT_UPPER = ("gcs.flight.procedure", "gcs.flight.run", "gcs.flight.safety", "gcs.flight.replan",
                 "gcs.flight.host")

#: package (as a path prefix) -> module prefixes it must not import
RULES: dict[str, tuple[str, ...]] = {
    "planner": ("gcs",),
    "gcs/flight": ("gcs.service", "gcs.api", "gcs.cli", "gcs.sim", "gcs.fleet.commands",
                   "gcs.fleet.provision"),
    "gcs/flight/link": (*_FLIGHT_UPPER, "gcs.fleet"),
    "gcs/flight/procedure": (*_FLIGHT_UPPER[1:], "gcs.fleet.commands", "gcs.fleet.provision"),
    "gcs/flight/run": ("gcs.flight.host",),
    "gcs/flight/safety": ("gcs.flight.host",),
    "gcs/flight/replan": ("gcs.flight.host",),
    "gcs/fleet": ("gcs.flight.run", "gcs.flight.safety", "gcs.flight.replan", "gcs.flight.host",
                  "gcs.sim", "gcs.service", "gcs.api", "gcs.cli"),
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
    if not (ROOT / prefix).exists():
        pytest.skip(f"{prefix} does not exist")
    assert _violations(prefix, RULES[prefix]) == []


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
#: reason in `LONG`.
MODULE_LINES = 400
FUNCTION_LINES = 80
#: The trees held to those lengths.
LENGTH_TREES = ("planner", "gcs")

#: What stays long, and why, one line each: a module by its path, a function by
#: ``path::name`` (a nested function or a method: ``path::outer.name``). Every other module
#: or function is split by concept once it grows past the limit, and an entry goes once its
#: module or function is no longer long.
LONG: dict[str, str] = {
    # modules
    "gcs/flight/run/executor.py":
        "the flight's one coordinator: phases, pause, abort, faults and replans all act on the "
        "same vehicles, streams and clock",
    "gcs/flight/replan/replan.py":
        "one class, `Replanner`: a replan's lifecycle from request to switch or miss",
    "gcs/flight/procedure/vehicle.py":
        "the procedure's link-level steps, one short coroutine each, and the executor's view "
        "of a vehicle (`VehicleStatus`) that they update",
    "planner/scp/qp.py":
        "the staged variables' layout, the structure shared by groups of one shape and the "
        "group QP's rows: every part indexes the same variables",
    "planner/scp/separation.py":
        "the pair geometry of one constraint: pair selection, directions, margins and row "
        "values share the same step and interval formulas",
    "planner/families/generators.py":
        "a catalogue of scenario families, each a short independent function",
    "planner/model/scenario.py":
        "the scenario contract: its dataclasses and the parser that names every field",
    "planner/methods/sequence.py":
        "the formation-sequence contract: its parser, the legs and their stitching",
    "gcs/api/routes/missions.py":
        "the routes of one resource (missions), each short, sharing its helpers",
    "planner/result.py":
        "the plan contract: its dataclasses and the reader that checks every field",
    "gcs/fleet/fleetfile.py":
        "the fleet-file contract: `FlightOptions` (a table of fields) and the parser",
    "gcs/api/routes/flights.py":
        "the routes of one resource (flights), each short, sharing its helpers",
    "gcs/cli/plan_cmd.py":
        "one command: its options, progress lines and summary table",
    "gcs/service/flights.py":
        "one class, `FleetService`: a flight's commands and its run to the stored record",
    "gcs/service/store.py":
        "the two tables and their queries, one transaction each",
    "planner/methods/landing.py":
        "one algorithm: touchdown points, the landing plan and its escape move",
    "gcs/api/schemas.py":
        "the API's documents, a table of pydantic models derived from the planner's types",
    "planner/model/fixed.py":
        "fixed trajectories: the dataclasses and the braking, landing and dropped motions",
    "planner/methods/assignment.py":
        "one algorithm: the certified sparse assignment and its dense fallback",
    "gcs/wire.py":
        "the MAVLink facts, a table of encodings each defined once",
    "gcs/sim/messages.py":
        "a table of encoders, one short function per message the mock sends",
    "gcs/flight/run/record.py":
        "the flight record and its summary, whose keys are one contract",
    # functions
    "gcs/cli/fly_cmd.py::run":
        "one command's run: its nested handlers share the flight, its record and the signals",
    "gcs/cli/fly_cmd.py::run.fly":
        "the flight under the CLI: events, Ctrl-C, pause and the control socket in one place",
    "gcs/flight/run/record.py::summarise":
        "builds the summary document key by key, in the order of its contract",
    "gcs/cli/mock_cmd.py::run":
        "one command's run: options to mock fleet, ports and signals",
    "gcs/api/app.py::create_app":
        "the application's wiring: lifespan, routers and error handlers in one place",
    "planner/scp/loop.py::run_scp":
        "the SCP loop read top to bottom: seeding, iterations, stop rules and outcome",
}


def _functions(tree: ast.AST, prefix: str = "") -> Iterable[tuple[str, int]]:
    """(dotted name, lines) of every function and method in `tree`, nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            name = f"{prefix}{node.name}"
            if not isinstance(node, ast.ClassDef):
                yield name, (node.end_lineno or node.lineno) - node.lineno + 1
            yield from _functions(node, name + ".")
        else:
            yield from _functions(node, prefix)


def long_parts(root: Path, trees: Iterable[str] = LENGTH_TREES) -> dict[str, int]:
    """Every module over MODULE_LINES lines and function over FUNCTION_LINES under `root`'s
    `trees`, as `LONG` names them, with its length."""
    found: dict[str, int] = {}
    for tree in trees:
        for path in sorted((root / tree).rglob("*.py")):
            rel = str(path.relative_to(root))
            text = path.read_text()
            if (lines := len(text.splitlines())) > MODULE_LINES:
                found[rel] = lines
            for name, length in _functions(ast.parse(text, filename=rel)):
                if length > FUNCTION_LINES:
                    found[f"{rel}::{name}"] = length
    return found


def test_long_modules_and_functions_say_why() -> None:
    """One job per module and per function: a long one is split, or `LONG` says why not."""
    found = long_parts(ROOT)
    assert {name: found[name] for name in found if name not in LONG} == {}


def test_every_long_entry_is_still_long() -> None:
    """An entry goes once its module or function is short, so the list stays honest."""
    assert sorted(set(LONG) - set(long_parts(ROOT))) == []


def _long_function(name: str, indent: str = "") -> str:
    """A function of FUNCTION_LINES + 1 lines (its def and FUNCTION_LINES statements)."""
    body = [f"{indent}    x{n} = {n}" for n in range(FUNCTION_LINES)]
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
