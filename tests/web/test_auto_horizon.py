"""The page's form takes `steps: "auto"`: the service plans at the horizon the planner
chooses, the plan panel says so, and a bad steps text is named next to the field."""

from __future__ import annotations

import httpx
from playwright.sync_api import Page, expect

from tests.api.support import ServiceProcess
from tests.web.support import CROSSING, fill_scenario


def test_the_form_plans_with_steps_auto(page: Page, service: ServiceProcess) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    fill_scenario(page, "browser-auto", 50, CROSSING)
    page.fill("#f-steps", "auto")
    page.click("#plan-button")
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    mission_id = page.locator("#mission-title").inner_text().split("·")[1].strip()
    mission = httpx.get(f"{service.base_url}/api/missions/{mission_id}").json()
    assert mission["scenario"]["steps"] == "auto"
    chosen = mission["plan"]["horizon"]["chosen_steps"]
    assert mission["plan"]["scenario"]["steps"] == chosen
    expect(page.locator("#solver-figures")).to_contain_text(
        f"4 × {chosen} (dt 0.2 s), steps chosen by the planner")


def test_a_steps_text_that_is_not_auto_is_named_next_to_the_field(page: Page) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    page.fill("#f-steps", "soon")
    page.click("#plan-button")
    expect(page.locator('[data-error-for~="steps"]')).to_contain_text('or "auto"')
    expect(page.locator("#f-steps")).to_have_class("invalid")
