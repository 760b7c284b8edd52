"""The documentation site builds offline and strictly, keeps its sections, and the README stays
a short, correct entry point.

The site is built with `mkdocs build --strict` exactly as `make docs` does, in a subprocess
whose sockets refuse to connect, so a theme or plugin that fetches anything fails the build.
A second set of builds copies the docs, breaks them on purpose and checks that the strict
build refuses them: the first test could not pass on a broken site.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml  # type: ignore[import-untyped]

from gcs.phases import FORMER_EVENT_KINDS, EventKind, FlightPhase, VehiclePhase
from gcs.service.statuses import STATUS_OF_PHASE, FlightStatus, MissionStatus
from tests.paths import ROOT

__all__: list[str] = []

pytest.importorskip("mkdocs")
pytest.importorskip("material")

#: The navigation sections the documentation promises (docs/development/architecture.md,
#: "Documentation layout").
SECTIONS = (
    "Getting started",
    "Concepts",
    "Planning formats",
    "Flying and the fleet file",
    "The service, settings and deployment",
    "Security",
    "Real vehicles",
    "Benchmarks",
    "Development",
)

#: Runs mkdocs with every socket connection refused: the build must need no network.
OFFLINE_MKDOCS = """
import socket, sys
def _refuse(*args, **kwargs):
    raise OSError("network access during the docs build")
socket.socket.connect = _refuse
socket.socket.connect_ex = _refuse
socket.create_connection = _refuse
from mkdocs.__main__ import cli
sys.exit(cli(sys.argv[1:]))
"""

ISSUE_NUMBER = re.compile(r"\bissues?\s+#?\d+|\bissue\s*#\d+", re.IGNORECASE)
MARKDOWN_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    """`mkdocs build --strict` of `config` into `site`, offline; returns the finished process."""
    return subprocess.run(
        [sys.executable, "-c", OFFLINE_MKDOCS, "build", "--strict", "--config-file",
         str(config), "--site-dir", str(site)],
        capture_output=True, text=True, timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )


def nav_pages(nav: list[Any]) -> Iterator[tuple[str, str]]:
    """(section title, page path) for every page of a nav section, depth first."""
    for entry in nav:
        for title, value in entry.items():
            if isinstance(value, str):
                yield title, value
            else:
                for _, page in nav_pages(value):
                    yield title, page


@pytest.fixture(scope="module")
def config() -> dict[str, Any]:
    return yaml.safe_load((ROOT / "mkdocs.yml").read_text())


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = build(ROOT / "mkdocs.yml", out)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def test_the_site_builds_strictly_offline_without_web_fonts(
    site: Path, config: dict[str, Any],
) -> None:
    assert config["theme"]["name"] == "material"
    assert config["theme"]["font"] is False
    pages = list(site.rglob("*.html"))
    assert len(pages) > 10
    for page in pages:
        text = page.read_text()
        assert "fonts.googleapis.com" not in text and "fonts.gstatic.com" not in text, page


def test_every_section_is_in_the_nav_and_built(site: Path, config: dict[str, Any]) -> None:
    titles = [next(iter(entry)) for entry in config["nav"]]
    for section in SECTIONS:
        assert section in titles, f"nav has no section {section!r}"
    built: dict[str, list[Path]] = {}
    for section, page in nav_pages(config["nav"]):
        html = site / Path(page).with_suffix(".html")
        assert html.is_file(), f"{page} ({section}) was not built"
        built.setdefault(section, []).append(html)
    assert set(SECTIONS) <= set(built)


def test_links_problems_are_errors_in_the_config(config: dict[str, Any]) -> None:
    validation = config["validation"]
    for key in ("omitted_files", "unrecognized_links", "anchors", "absolute_links"):
        assert validation[key] == "warn", key  # --strict turns warnings into errors
    assert config.get("strict") is True


@pytest.mark.parametrize("breakage", ["broken link", "broken anchor", "page not in nav"])
def test_a_broken_site_fails_the_strict_build(tmp_path: Path, breakage: str) -> None:
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    if breakage == "broken link":
        with (tmp_path / "docs" / "concepts.md").open("a") as page:
            page.write("\nSee [the missing page](no-such-page.md).\n")
        needle = "no-such-page.md"
    elif breakage == "broken anchor":
        with (tmp_path / "docs" / "concepts.md").open("a") as page:
            page.write("\nSee [nowhere](security.md#no-such-heading).\n")
        needle = "no-such-heading"
    else:
        (tmp_path / "docs" / "forgotten.md").write_text("# Forgotten\n")
        needle = "forgotten.md"
    done = build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert done.returncode != 0
    assert needle in done.stdout + done.stderr


def test_readme_is_short_and_starts_with_the_two_commands() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 250
    head = "\n".join(lines[:15])
    assert re.search(r"^\s*make run\b", head, re.M), "make run is not in the first 15 lines"
    assert re.search(r"^\s*make test\b", head, re.M), "make test is not in the first 15 lines"


def test_readme_relative_links_point_at_files() -> None:
    text = (ROOT / "README.md").read_text()
    targets = [t for t in MARKDOWN_LINK.findall(text)
               if not re.match(r"[a-z][a-z0-9+.-]*:", t) and not t.startswith("#")]
    assert targets, "the README links into the docs"
    missing = [t for t in targets if not (ROOT / t.split("#")[0]).exists()]
    assert not missing, missing


def test_no_page_names_an_issue_number() -> None:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")),
             *sorted((ROOT / "bench").glob("*.md"))]
    found = [f"{path.relative_to(ROOT)}: {match.group(0)}" for path in files
             for match in ISSUE_NUMBER.finditer(path.read_text())]
    assert not found, found


def test_the_architecture_page_names_every_module() -> None:
    """A module added to the ground station is placed on the architecture page (by its file
    name, in backticks), so the page shows the packages as they are."""
    text = (ROOT / "docs" / "development" / "architecture.md").read_text()
    unnamed = [str(m.relative_to(ROOT)) for m in sorted((ROOT / "gcs").rglob("*.py"))
               if m.name != "__init__.py" and f"`{m.name}`" not in text]
    assert unnamed == []


def test_concepts_page_names_every_status_and_phase() -> None:
    """The glossary lists the defined statuses and phases (gcs/service/statuses.py,
    gcs/phases.py); a new one must be documented."""
    text = (ROOT / "docs" / "concepts.md").read_text()
    for value in [*MissionStatus, *FlightStatus, *FlightPhase, *VehiclePhase]:
        assert f"`{value}`" in text, value


#: Where the former name of a flight remains (a contract with clients or stored data): the
#: glossary's words for it, and the module that keeps it.
FORMER_NAME = [("`/api/executions`", "gcs/api/routes/__init__.py"),
               ("`/api/missions/{id}/executions`", "gcs/api/routes/flights.py"),
               ("list key `executions`", "gcs/api/routes/flights.py"),
               ("`execution_id`", "gcs/api/routes/flights.py"),
               ("`statuses.execution`", "gcs/service/statuses.py"),
               ("`links.executions`", "gcs/api/routes/missions.py"),
               ("storage table `executions`", "gcs/service/store.py")]
_EXECUTION = re.compile(r"\bexecution(s|_id)?\b")


def test_the_glossary_lists_every_place_the_former_name_remains() -> None:
    """*execution* is said only where the glossary says it remains, and it does remain there:
    a new use (or one gone) must change the glossary too."""
    text = " ".join((ROOT / "docs" / "concepts.md").read_text().split())
    for words, module in FORMER_NAME:
        assert words in text, words
        assert _EXECUTION.search((ROOT / module).read_text()), module
    sources = [*sorted((ROOT / "gcs").rglob("*.py")), *sorted((ROOT / "web").rglob("*.js"))]
    saying = {str(p.relative_to(ROOT)) for p in sources if _EXECUTION.search(p.read_text())}
    describing = {"gcs/api/routes/status.py"}  # the OpenAPI text of `statuses.execution`
    assert saying <= {module for _, module in FORMER_NAME} | describing, saying


def test_concepts_page_says_what_the_code_defines() -> None:
    """The glossary's words are the code's: the flight's phase -> status table is
    `STATUS_OF_PHASE`, every event kind named is a current one and every current one is
    named, and the classes named for a flight and its documents exist where the page says."""
    text = (ROOT / "docs" / "concepts.md").read_text()
    rows = re.findall(r"^\| `(\w+)` \| `(\w+)` \|$", text, re.M)
    assert dict(rows) == {str(p): str(s) for p, s in STATUS_OF_PHASE.items()}
    kinds = text.split("### Event kinds")[1].split("\n## ")[0]
    named = set(re.findall(r"`(\w+)`", kinds)) - {"event_kinds", "land_faulty", "land_timeout"}
    assert named - set(FORMER_EVENT_KINDS) <= {str(k) for k in EventKind}, named
    assert {str(k) for k in EventKind} - named == set(), "event kinds the glossary leaves out"
    assert f"`{EventKind.FLIGHT_START}`" in kinds
    for name, module in [("FlightExecutor", "gcs/flight/run/executor.py"),
                         ("FlightHandle", "gcs/flight/host/flight_handle.py"),
                         ("RemoteFlight", "gcs/service/remote_flight.py"),
                         ("LiveFlight", "gcs/service/live_flight.py"),
                         ("FlightEvent", "gcs/documents.py"),
                         ("FlightSnapshot", "gcs/documents.py"),
                         ("VehicleSnapshot", "gcs/documents.py"),
                         ("ReplanDocument", "gcs/documents.py"),
                         ("ReplanRecord", "gcs/flight/replan/record.py"),
                         ("FlightContext", "gcs/flight/procedure/context.py"),
                         ("VehicleStatus", "gcs/flight/procedure/vehicle.py")]:
        assert f"`{name}`" in text and f"class {name}" in (ROOT / module).read_text(), name
