"""Fly only what is on screen: a form change marks the results stale and disables Fly until
the form is planned; a rejected plan never leaves an older one flyable; errors go once fixed;
nothing to play or fly before a plan; missions have names; the plan-to-fleet mapping shows."""

from __future__ import annotations

import json
from collections.abc import Callable

import httpx
from playwright.sync_api import Page, Route, expect

from tests.api.support import ServiceProcess
from tests.web.support import CROSSING, fill_scenario, plan, shown_mission_id


def test_nothing_to_play_or_fly_before_a_plan(page: Page) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)  # preset loaded
    expect(page.locator("#empty-note")).to_be_visible()
    expect(page.locator("#play")).to_be_hidden()
    expect(page.locator("#fly-view")).to_be_hidden()
    expect(page.locator("#fly-button")).to_be_disabled()
    expect(page.locator("#fly-reason")).to_have_text("plan a mission first")
    # The fleet is on screen before any plan: its link, mode and arming can be checked.
    expect(page.locator("#vehicle-state tbody tr")).to_have_count(4)
    expect(page.locator("#plot3d")).to_be_hidden()  # no empty plots before a plan
    # The vehicle count is for the generated presets only; paper cases say their own size.
    expect(page.locator("#preset-count")).to_be_hidden()
    option = page.locator('#preset option[value="example:paper-circle4"]')
    expect(option).to_have_text("paper-circle4 · 4 vehicles")
    page.select_option("#preset", "gen:circle")
    expect(page.locator("#preset-count")).to_be_visible()
    page.fill("#preset-count", "6")
    page.click("#preset-load")
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(6)
    expect(page.locator("#f-name")).to_have_value("circle6")


def test_a_changed_form_cannot_fly_the_plan_shown_and_loads_nothing_from_elsewhere(
    open_page: Callable[..., Page], service: ServiceProcess
) -> None:
    """Field laptops are often offline too: every request the page makes, from loading to
    planning (and so fetching plotly.js) and flying, goes to the service."""
    urls: list[str] = []
    page = open_page(before=lambda p: p.on("request", lambda r: urls.append(r.url)))
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    fill_scenario(page, "shown-plan", 50, CROSSING)
    first = plan(page)
    assert any(u.endswith("/vendor/plotly.min.js") for u in urls)
    assert any(u.endswith("/flyview.js") for u in urls)
    # The service has the pause and fleet-command endpoints: their buttons are there, and
    # Pause is disabled while nothing flies.
    expect(page.locator("#pause-button")).to_be_visible()
    expect(page.locator("#pause-button")).to_be_disabled()
    expect(page.locator(".fleet-commands")).to_be_visible()
    fly = page.locator("#fly-button")
    banner = page.locator("#stale-banner")
    expect(fly).to_be_enabled()
    expect(banner).to_be_hidden()

    page.fill("#f-steps", "12")  # the plan on screen is no longer the form's
    expect(banner).to_be_visible()
    expect(banner).to_contain_text("form has changed")
    expect(page.locator("#fly-panel")).to_have_class("panel stale")
    expect(fly).to_be_disabled()
    expect(page.locator("#fly-reason")).to_contain_text("press Plan")
    page.fill("#f-steps", "50")  # back to what was planned: the results are the form's again
    expect(banner).to_be_hidden()
    expect(fly).to_be_enabled()

    # A rejected request: the older plan stays visible, marked, and cannot be flown, even
    # once the form reads as it did when that plan was made.
    page.fill("#f-dt", "-1")
    page.click("#plan-button")
    expect(page.locator("#plan-state")).to_contain_text("rejected (422)")
    expect(page.locator('[data-error-for~="dt"]')).to_contain_text("dt: must be positive")
    expect(banner).to_contain_text("rejected")
    expect(fly).to_be_disabled()
    page.fill("#f-dt", "0.2")  # fixed: its error goes at once
    expect(page.locator('[data-error-for~="dt"]')).to_have_text("")
    expect(page.locator("#f-dt")).not_to_have_class("invalid")
    expect(page.locator("#plan-state")).to_have_text("edited: press Plan")  # not "rejected"
    expect(fly).to_be_disabled()

    # Planned again: Fly flies exactly the mission now on screen.
    page.fill("#f-steps", "55")
    second = plan(page)
    assert second != first
    expect(fly).to_be_enabled()
    posted: list[str] = []

    def refuse(route: Route) -> None:
        posted.append(route.request.url)
        route.fulfill(status=409, content_type="application/json",
                      body=json.dumps({"status": 409, "field": "fleet",
                                       "reason": "test: not flying"}))

    page.route("**/api/missions/*/flights", refuse)
    fly.click()
    expect(page.locator("#flight-status")).to_contain_text("refused (409)")
    assert posted == [f"{service.base_url}/api/missions/{second}/flights"]
    mission = httpx.get(f"{service.base_url}/api/missions/{second}").json()
    assert mission["scenario"]["steps"] == 55 and mission["scenario"]["dt"] == 0.2
    foreign = [u for u in urls if not u.startswith(service.base_url) and not u.startswith("data:")]
    assert foreign == []


def test_an_edited_preset_is_named_apart_and_the_mapping_shows_mismatches(page: Page) -> None:
    expect(page.locator("#f-name")).to_have_value("paper-circle4")
    page.fill('input[data-field="vehicles[0].start[2]"]', "1.3")
    expect(page.locator("#f-name")).to_have_value("paper-circle4-edited")
    page.fill("#f-name", "survey-north")  # the operator's own name is kept
    page.fill('input[data-field="vehicles[0].start[2]"]', "1.2")
    expect(page.locator("#f-name")).to_have_value("survey-north")
    # Five plan vehicles, four mock vehicles: Fly says which one has no vehicle.
    page.click("#add-vehicle")
    page.fill('input[data-field="vehicles[4].id"]', "extra")
    for axis, (s, g) in enumerate(zip((0.5, 0.5, 1.0), (0.5, 0.5, 2.0), strict=True)):
        page.fill(f'input[data-field="vehicles[4].start[{axis}]"]', str(s))
        page.fill(f'input[data-field="vehicles[4].goal[{axis}]"]', str(g))
    mission_id = plan(page)
    expect(page.locator("#mission-title")).to_contain_text("survey-north")
    listed = page.locator(f'#mission-list li[data-id="{mission_id}"]')
    expect(listed).to_contain_text("survey-north")
    expect(page.locator("#mapping-missing")).to_contain_text("not in the fleet: extra")
    expect(page.locator("#fly-button")).to_be_disabled()
    expect(page.locator("#fly-reason")).to_have_text(
        "1 plan vehicle is not in the fleet of 4: restart the service with 5 mock vehicles "
        "(fleetplan serve --mock 5) or a fleet file naming them "
        "(fleetplan serve --fleet FLEET.json)")
    assert shown_mission_id(page) == mission_id


def test_the_first_preset_never_loads_over_typing(open_page: Callable[..., Page]) -> None:
    held: list[Route] = []

    def hold(p: Page) -> None:
        p.route("**/api/examples/paper-circle4", lambda route: held.append(route))

    page = open_page(before=hold)
    page.wait_for_function("document.querySelectorAll('#preset-examples option').length > 0")
    page.fill("#f-name", "typed-first")
    page.fill("#f-steps", "77")
    assert len(held) == 1  # the preset's scenario arrives only now
    expect(page.locator("#plan-button")).to_be_disabled()  # the page waits for its preset
    held[0].continue_()
    # Plan enables once the preset's answer has been taken in (and ignored).
    expect(page.locator("#plan-button")).to_be_enabled()
    expect(page.locator("#f-name")).to_have_value("typed-first")
    expect(page.locator("#f-steps")).to_have_value("77")
