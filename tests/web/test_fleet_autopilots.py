"""The fleet table names each vehicle's autopilot: a column where the fleet mixes PX4 and
ArduPilot, each vehicle cell's title otherwise (and on a phone, where the column would not
fit beside the phase and command columns)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable

from playwright.sync_api import Page, Route, expect

from tests.web.conftest import PHONE

VEHICLES = "**/api/vehicles"


def _autopilots(kinds: list[str]) -> Callable[[Route], None]:
    """A route answering GET /api/vehicles with the service's own answer, its vehicles flown
    as `kinds` in turn."""
    def handle(route: Route) -> None:
        if route.request.method != "GET":
            route.fallback()
            return
        answer = route.fetch()
        body = answer.json()
        for n, v in enumerate(body["vehicles"]):
            v["autopilot"] = kinds[n % len(kinds)]
        route.fulfill(response=answer, body=json.dumps(body))
    return handle


def _heads(page: Page) -> list[str]:
    return page.locator("#vehicle-state thead th").all_inner_texts()


def test_a_mixed_fleet_has_an_autopilot_column(open_page: Callable[..., Page]) -> None:
    page = open_page(before=lambda p: p.route(VEHICLES, _autopilots(["px4", "ardupilot"])))
    cells = page.locator('#vehicle-state tbody td[data-key="autopilot"]')
    expect(cells.first).to_be_visible(timeout=30_000)
    assert "autopilot" in _heads(page)
    texts = cells.all_inner_texts()
    assert set(texts) == {"PX4", "ArduPilot"} and texts[:2] == ["PX4", "ArduPilot"]
    first = page.locator('#vehicle-state tbody tr[data-id] td[data-key="id"]').first
    assert first.get_attribute("title", timeout=5_000).endswith("flown as PX4")


def test_a_uniform_fleet_names_its_autopilot_in_each_vehicle_cell(
        open_page: Callable[..., Page]) -> None:
    page = open_page(before=lambda p: p.route(VEHICLES, _autopilots(["ardupilot"])))
    first = page.locator('#vehicle-state tbody tr[data-id] td[data-key="id"]').first
    expect(first).to_have_attribute("title", re.compile(r"^\S+: flown as ArduPilot$"),
                                    timeout=30_000)
    assert "autopilot" not in _heads(page)
    assert page.locator('#vehicle-state td[data-key="autopilot"]').count() == 0


def test_on_a_phone_a_mixed_fleet_keeps_its_autopilot_in_the_titles(
        open_page: Callable[..., Page]) -> None:
    page = open_page(PHONE, before=lambda p: p.route(VEHICLES, _autopilots(["px4", "ardupilot"])))
    head = page.locator('#vehicle-state thead th[data-key="autopilot"]')
    expect(head).to_have_count(1, timeout=30_000)
    expect(head).to_be_hidden()
    expect(page.locator('#vehicle-state tbody td[data-key="autopilot"]').first).to_be_hidden()
    widths = page.evaluate("""() => {
        const table = document.querySelector('#vehicle-state');
        return [table.scrollWidth, table.closest('.table-wrap').clientWidth];
    }""")
    assert widths[0] <= widths[1], widths
