"""A long plan in the page: the iteration under way and the time elapsed while it computes,
and Cancel, which stops it through the API (the mission ends failed, "cancelled by the
operator") and goes away with the clock."""

from __future__ import annotations

import json

import httpx
from playwright.sync_api import Page, expect

from planner.families.generators import antipodal_sphere
from tests.paths import EXAMPLES

#: 100 vehicles crossing a sphere's centre as one fleet: minutes of planning (its first SCP
#: iteration alone outlasts this test's waits).
LONG = antipodal_sphere(100) | {"method": "whole"}


def test_a_long_plan_shows_its_progress_and_cancel_stops_it(page: Page) -> None:
    page.click("#sequence-panel summary")
    page.fill("#sequence-json", json.dumps(LONG))
    cancel = page.locator("#plan-cancel")
    expect(cancel).to_be_hidden()
    page.click("#sequence-plan")
    expect(cancel).to_be_visible()
    expect(page.locator("#plan-elapsed")).to_contain_text("elapsed")
    expect(page.locator("#plan-state")).to_contain_text("planning… iteration", timeout=60_000)
    expect(page.locator("#plan-state")).to_contain_text("· whole")
    cancel.click()
    expect(page.locator("#plan-state")).to_contain_text(
        "planning failed: cancelled by the operator", timeout=60_000)
    expect(cancel).to_be_hidden()
    expect(page.locator("#plan-elapsed")).to_have_text("")
    expect(page.locator("#plan-button")).to_be_enabled()
    # A plan posted at once (the cancelled plan's worker may be restarting) is planned.
    base = page.url.split("/", 3)
    small = json.loads((EXAMPLES / "paper-circle4.json").read_text())
    answer = httpx.post(f"{base[0]}//{base[2]}/api/missions?wait=90", json=small, timeout=120)
    assert answer.json()["status"] == "planned", answer.text
