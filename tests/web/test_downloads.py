"""A stored mission's files from the page: its plan, trajectory CSV, Skybrush show and
validation report, each a link to the service's route that answers with that file."""

from __future__ import annotations

import json

from playwright.sync_api import Page, expect

from tests.api.support import QUICK_PAIR
from tests.web.support import shown_mission_id


def test_a_planned_mission_offers_its_files_and_each_link_answers(page: Page) -> None:
    page.click("#sequence-panel summary")
    page.fill("#sequence-json", json.dumps(QUICK_PAIR))
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("converged, verified", timeout=60_000)
    mission = shown_mission_id(page)
    base = f"/api/missions/{mission}"
    links = page.locator("#plan-downloads a")
    expect(links).to_have_count(4)
    report = page.locator('#plan-downloads a[data-download="report"]')
    expect(report).to_have_attribute("href", f"{base}/report.html")
    expect(report).to_have_attribute("download", f"report-{mission}.html")
    expect(report).to_have_text("validation report (HTML)")
    expect(page.locator('#plan-downloads a[data-download="show"]')).to_have_attribute(
        "href", f"{base}/show.skyc")
    answers = {a.get_attribute("data-download"): page.request.get(a.evaluate("a => a.href"))
               for a in links.all()}
    assert all(r.ok for r in answers.values()), {k: r.status for k, r in answers.items()}
    html = answers["report"]
    assert html.headers["content-type"].startswith("text/html")
    assert html.text().lstrip().lower().startswith("<!doctype html")
    assert "quick-pair" in html.text()
    assert answers["show"].body()[:2] == b"PK"  # a ZIP holding show.json
    assert json.loads(answers["plan"].text())["status"] == "converged"
    assert answers["trajectory"].text().splitlines()[0].startswith("vehicle,t,x,y,z")
