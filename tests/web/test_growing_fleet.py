"""Fly beside a mock fleet that grows to the plan (`serve --mock auto`): the mocks to be added
are said and Fly is enabled; past the fleet's limit, Fly names the setting to raise. The
shared service's fleet is fixed (`--mock 4`): its answers are given a `grows_to` here. The
generated random preset's starts are R apart in x-y, so the mocks can climb to them."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
from playwright.sync_api import Page, Route, expect

from tests.web.support import plan

#: What the fleet's answers (GET /api/vehicles, /api/status) are changed to, read per answer.
FLEET: dict[str, Any] = {}


def _growing(route: Route) -> None:
    if route.request.method != "GET":
        route.fallback()
        return
    answer = route.fetch()
    body = answer.json()
    body["fleet"].update(FLEET)
    if "vehicles" in body and isinstance(body["vehicles"], list):
        body["vehicles"] = body["vehicles"][:body["fleet"]["vehicles"]]
    route.fulfill(response=answer, body=json.dumps(body))


def _routes(page: Page) -> None:
    page.route("**/api/vehicles", _growing)
    page.route("**/api/status", _growing)


def test_fly_says_the_mocks_added_for_the_plan_and_the_limit_past_it(
        open_page: Callable[..., Page]) -> None:
    FLEET.clear()
    FLEET.update(grows_to=8)
    page = open_page(before=_routes)
    expect(page.locator("#service-status")).to_contain_text(
        "4 mock vehicles (up to 8 as plans need)", timeout=30_000)
    expect(page.locator("#f-name")).to_have_value("paper-circle4")
    page.click("#add-vehicle")  # a fifth vehicle, low in a corner
    page.fill('input[data-field="vehicles[4].id"]', "extra")
    for axis, (s, g) in enumerate(zip((0.5, 0.5, 1.0), (0.5, 0.5, 2.0), strict=True)):
        page.fill(f'input[data-field="vehicles[4].start[{axis}]"]', str(s))
        page.fill(f'input[data-field="vehicles[4].goal[{axis}]"]', str(g))
    plan(page)
    expect(page.locator("#mapping")).to_contain_text("extra→mock 5")
    expect(page.locator("#mapping")).to_contain_text("1 mock vehicle added at Fly")
    expect(page.locator("#mapping-missing")).to_have_count(0)
    expect(page.locator("#fly-button")).to_be_enabled()
    # A fleet of 3 that may grow to 4: the fifth plan vehicle has no mock.
    FLEET.update(vehicles=3, ids=["uav1", "uav2", "uav3"], grows_to=4)
    expect(page.locator("#fly-reason")).to_have_text(
        "the plan has 5 vehicles, more than the mock fleet may grow to (4, setting "
        "mock_max_vehicles): restart the service with FLEETPLAN_MOCK_MAX_VEHICLES=5 (or "
        "fleetplan serve --mock 5) or a fleet file naming them "
        "(fleetplan serve --fleet FLEET.json)", timeout=10_000)
    expect(page.locator("#mapping-missing")).to_contain_text("not in the fleet: extra")
    expect(page.locator("#fly-button")).to_be_disabled()


def test_a_generated_random_fleet_has_its_starts_r_apart_horizontally(page: Page) -> None:
    scenarios = page.evaluate("""async () => {
        const { randomScenario } = await import("/presets.js");
        return [randomScenario(128), randomScenario(40)];
    }""")
    for scenario in scenarios:
        starts = np.array([v["start"] for v in scenario["vehicles"]])
        i, j = np.triu_indices(len(starts), k=1)
        gaps = np.linalg.norm(starts[i, :2] - starts[j, :2], axis=1)
        assert gaps.min() >= scenario["min_separation"]
