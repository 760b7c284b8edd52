"""Take docs/screenshot.png of a running service's page with Playwright and Debian's Chromium.

    .venv/bin/fleetplan serve --port 8000 --mock 8 &
    .venv/bin/python docs/screenshot.py http://127.0.0.1:8000/ docs/screenshot.png [--fly]

Loads the paper's 8-vehicle circle preset, plans it and (with --fly) flies it on the mock
vehicles, capturing the page mid-flight.
"""

from __future__ import annotations

import sys

from playwright.sync_api import expect, sync_playwright


def main(url: str, out: str, fly: bool) -> None:
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", headless=True)
        page = browser.new_page(viewport={"width": 1500, "height": 1250})
        page.goto(url)
        expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
        page.select_option("#preset", "example:paper-circle8")
        page.click("#preset-load")
        expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(8)
        page.click("#plan-button")
        expect(page.locator("#min-separation-value")).to_be_visible(timeout=120_000)
        page.locator("#time-slider").fill("120")
        page.locator("#time-slider").dispatch_event("input")
        if fly:
            page.click("#fly-button")
            expect(page.locator("#execution-status")).to_contain_text("running", timeout=120_000)
            page.wait_for_timeout(12_000)
        page.wait_for_timeout(1000)
        page.evaluate("window.scrollTo(0, 0)")
        page.screenshot(path=out)
        browser.close()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], "--fly" in sys.argv[3:])
