"""`fleetplan report`: one self-contained HTML file whose checks and worst moments agree
with the verifier, that says FAIL when a limit is broken, and that Chromium draws offline
with every chart (no request leaves the page)."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from gcs.cli.main import main
from gcs.show.report import report_facts, report_html
from planner import Plan
from planner.methods.sequence import plan_sequence
from tests.paths import EXAMPLES
from tests.support.shows import light_design as _design


@pytest.fixture(scope="module")
def lit() -> Plan:
    plan = plan_sequence(_design()).to_plan()
    assert plan.ok, plan.problems()
    return plan


def test_the_figures_agree_with_the_verifier_and_the_motion(lit: Plan) -> None:
    facts = report_facts(lit)
    assert lit.verification is not None
    # nearest neighbours at the steps (k-d tree) against the verifier's pair minimum
    assert facts["distance"]["worst"] == pytest.approx(lit.verification.min_separation,
                                                       abs=1e-9)
    assert facts["distance"]["limit"] == 1.0
    assert facts["altitude"]["worst"] == pytest.approx(lit.positions()[:, :, 2].max())
    speeds = np.hypot(lit.velocities()[:, :, 0], lit.velocities()[:, :, 1])
    assert facts["speed_xy"]["worst"] == pytest.approx(speeds.max())
    assert facts["speed_xy"]["limit"] == pytest.approx(3.0 * np.sqrt(2.0))
    assert facts["thrust"]["limit"] == lit.scenario.limits.thrust_max


def test_a_passing_plan_passes_every_check(lit: Plan) -> None:
    text, passed = report_html(lit)
    assert passed
    assert text.count('class="pass"') >= 9 and 'class="fail"' not in text
    assert "<img class='lights'" in text  # the light strips of a lit show
    assert 'src="http' not in text and "src='http" not in text
    assert len(text.encode()) < 20e6


def test_a_broken_limit_is_a_failed_check_naming_the_drones(lit: Plan) -> None:
    slow = dataclasses.replace(lit.scenario.limits, velocity_max=np.array([0.05, 0.05, 0.05]))
    broken = dataclasses.replace(lit, scenario=dataclasses.replace(lit.scenario, limits=slow))
    text, passed = report_html(broken)
    assert not passed
    assert "Horizontal speed</td><td><span class=\"fail\">FAIL</span>" in text
    assert "drone(s): uav" in text


def test_the_cli_writes_it_and_says_the_verdict(lit: Plan, tmp_path: Path, capsys) -> None:
    plan_file = tmp_path / "plan.json"
    plan_file.write_text(json.dumps(lit.to_dict()))
    out = tmp_path / "report.html"
    assert main(["report", str(plan_file), "-o", str(out)]) == 0
    assert "every check passes" in capsys.readouterr().out
    assert out.read_text().startswith("<!doctype html>")
    scenario = EXAMPLES / "paper-circle4.json"
    assert main(["report", str(scenario), "-o", str(tmp_path / "x.html")]) == 2
    assert "is a scenario, not a plan" in capsys.readouterr().err
    assert not (tmp_path / "x.html").exists()


def _chromium() -> str:
    path = os.environ.get("FLEETPLAN_CHROMIUM", "/usr/bin/chromium")
    found = path if Path(path).exists() else shutil.which("chromium")
    if found:
        return found
    if os.environ.get("FLEETPLAN_REQUIRE_BROWSER") == "1":
        pytest.fail("Chromium not found (sudo apt-get install chromium)")
    pytest.skip("Chromium not found (sudo apt-get install chromium)")


def test_chromium_draws_every_chart_offline(lit: Plan, tmp_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    path = tmp_path / "report.html"
    path.write_text(report_html(lit)[0])
    requests: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=_chromium(), headless=True)
        try:
            page = browser.new_page()
            page.on("request", lambda request: requests.append(request.url))
            page.goto(path.as_uri())
            page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 8"
                                   " && [...document.querySelectorAll('.js-plotly-plot')]"
                                   ".every(d => d.querySelector('.main-svg .scatterlayer "
                                   ".trace'))", timeout=60_000)
            charts = page.evaluate("document.querySelectorAll('.js-plotly-plot').length")
        finally:
            browser.close()
    assert charts == 8
    assert [url for url in requests if not url.startswith(("file:", "data:"))] == []
