"""The page's side of the fleet-control API (pause/resume, fleet and vehicle commands,
battery/GPS/health, geodetic origin). Playwright routes stand in for states the mock service
cannot be put in on demand (a low battery, an unhealthy sensor, no GPS fix) and record what the
page sends; the payloads have the real API's shapes
(`gcs.flight.safety.health.health_report`), whose own side is tested in
tests/api/routes/test_fleet.py."""

from __future__ import annotations

import re
from typing import Any

import httpx
from playwright.sync_api import Page, expect

from gcs.frames import Geodetic, enu_to_geodetic
from tests.api.support import ServiceProcess
from tests.web.support import CROSSING, ORIGIN, fill_scenario, plan, planned_api


def test_commands_health_and_geodetic_reference(open_page, service: ServiceProcess) -> None:
    sent: list[tuple[str, Any]] = []
    page = open_page(before=lambda p: planned_api(p, service, sent))
    fill_scenario(page, "controls", 50, CROSSING)
    plan(page)

    # Fleet commands: visible, and sent with every fleet vehicle and the confirmation (each
    # answer waits for the vehicles' acknowledgements: awaited, not timed).
    expect(page.locator(".fleet-commands")).to_be_visible()
    expect(page.locator("#pause-button")).to_be_visible()
    expect(page.locator("#pause-button")).to_be_disabled()  # nothing is flying
    ids = httpx.get(f"{service.base_url}/api/vehicles").json()["fleet"]["ids"]
    page.click('.fleet-commands button[data-command="land"]')
    expect(page.locator("#command-result")).to_have_text(f"land sent to {len(ids)} vehicles",
                                                         timeout=30_000)
    page.click('.fleet-commands button[data-command="rtl"]')
    expect(page.locator("#command-result")).to_have_text(f"rtl sent to {len(ids)} vehicles",
                                                         timeout=30_000)
    # Per vehicle, from its row in the fleet table.
    first = page.locator("#vehicle-state tbody tr").first
    vid = first.get_attribute("data-id")
    first.locator('button[data-vehicle-command="hold"]').click()
    expect(page.locator("#command-result")).to_have_text(f"hold sent to {vid}",
                                                         timeout=30_000)
    assert sent == [
        ("/api/fleet/commands", {"command": "land", "vehicles": ids, "confirm": True}),
        ("/api/fleet/commands", {"command": "rtl", "vehicles": ids, "confirm": True}),
        (f"/api/vehicles/{vid}/commands", {"command": "hold", "confirm": True}),
    ]

    # Health columns appear with the data, coloured by level.
    heads = page.locator("#vehicle-state thead th").all_inner_texts()
    assert {"battery", "GPS", "health"} <= set(heads)
    rows = page.locator("#vehicle-state tbody tr")
    expect(rows.nth(0).locator('td[data-key="battery"]')).to_have_text("82 %")
    expect(rows.nth(0).locator('td[data-key="battery"]')).to_have_attribute("title", "16.1 V")
    expect(rows.nth(0).locator('td[data-key="battery"]')).to_have_class("cell-ok")
    expect(rows.nth(1).locator('td[data-key="battery"]')).to_have_class("cell-bad")
    expect(rows.nth(0).locator('td[data-key="gps"]')).to_have_text("3D 14")
    expect(rows.nth(0).locator('td[data-key="gps"]')).to_have_attribute(
        "title", "3D fix, 14 satellites, ±0.4 m")
    expect(rows.nth(0).locator('td[data-key="gps"]')).to_have_class("cell-ok")
    expect(rows.nth(1).locator('td[data-key="gps"]')).to_have_class("cell-bad")
    expect(rows.nth(0).locator('td[data-key="health"]')).to_have_text("ok")
    expect(rows.nth(1).locator('td[data-key="health"]')).to_have_text("3D gyro")
    expect(rows.nth(1).locator('td[data-key="health"]')).to_have_class("cell-bad")
    # Link quality: the loss of the last seconds (latency and the rest in its title), red from
    # 10 %.
    expect(rows.nth(0).locator('td[data-key="link_quality"]')).to_have_text("0.0 %")
    expect(rows.nth(0).locator('td[data-key="link_quality"]')).to_have_class("cell-ok")
    expect(rows.nth(1).locator('td[data-key="link_quality"]')).to_have_text("12 %")
    expect(rows.nth(1).locator('td[data-key="link_quality"]')).to_have_class("cell-bad")
    expect(rows.nth(1).locator('td[data-key="link_quality"]')).to_have_attribute(
        "title", "loss 12 % over the last 5 s (110 of 910 in all), latency 35 ms, 4 reordered, "
                 "1 duplicates, jitter 6.2 ms")

    # Geodetic reference: the workspace corners' coordinates (checked against gcs.frames'
    # exact ECEF conversion), a north arrow and a scale bar.
    expect(page.locator("#geo-label")).to_contain_text("47.397742° N 8.545594° E")
    corners = page.locator("#fly-view text.corner").all_text_contents()
    origin = Geodetic(ORIGIN["lat"], ORIGIN["lon"], ORIGIN["alt"])
    for text, (x, y) in zip(corners, [(0, 6), (6, 0)], strict=True):
        lat, lon = (float(v) for v in re.findall(r"(\d+\.\d+)°", text))
        exact = enu_to_geodetic([x, y, 0.0], origin)
        assert abs(lat - exact.lat) < 2e-6 and abs(lon - exact.lon) < 2e-6, (text, exact)
    expect(page.locator("#fly-view g.scale-bar")).to_have_attribute("data-metres", "1")
    expect(page.locator("#fly-view g.scale-bar text")).to_have_text("1 m")


def test_unavailable_endpoint_hides_its_button(open_page, service: ServiceProcess) -> None:
    """An endpoint listed but answering 404 (an older service behind a proxy, say): the
    button goes, and the operator is told."""
    sent: list[tuple[str, Any]] = []

    def routes(p: Page) -> None:
        planned_api(p, service, sent)
        p.route("**/api/fleet/commands", lambda route: route.fulfill(
            status=404, content_type="application/json", body='{"detail": "Not Found"}'))

    page = open_page(before=routes)
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    hold = page.locator('.fleet-commands button[data-command="hold"]')
    expect(hold).to_be_enabled()  # fleet commands need a fleet, not a plan
    hold.click()
    expect(page.locator("#command-result")).to_contain_text("not available on this service")
    expect(page.locator(".fleet-commands")).to_be_hidden()
    assert sent == []
