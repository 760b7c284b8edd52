"""Take the documentation's screenshots of a running service's page with Playwright and Debian's
Chromium: the fly screen at 1440x900 and the page at phone width (390x844).

    .venv/bin/fleetplan serve --port 8000 --mock 8 &
    .venv/bin/python docs/screenshot.py http://127.0.0.1:8000/ docs [--no-fly]

Loads the paper's 8-vehicle circle preset, plans it and flies it on the mock vehicles,
capturing docs/screenshot.png mid-flight and docs/screenshot-phone.png after it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from playwright.sync_api import expect, sync_playwright

CHROMIUM = "/usr/bin/chromium"


def main(url: str, out: Path, fly: bool) -> None:
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, headless=True)
        page = browser.new_page(viewport={"width": 1440, "height": 900})
        page.goto(url)
        expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
        page.select_option("#preset", "example:paper-circle8")
        page.click("#preset-load")
        expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(8)
        page.click("#plan-button")
        expect(page.locator("#min-separation-value")).to_be_visible(timeout=120_000)
        if fly:
            expect(page.locator("#fly-button")).to_be_enabled(timeout=30_000)
            page.click("#fly-button")
            expect(page.locator("#flight-status")).to_have_attribute(
                "data-status", "running", timeout=120_000)
            # Mid-flight: a few seconds into the plan.
            page.wait_for_function(
                "document.getElementById('flight-progress').value > 300", timeout=120_000)
        page.wait_for_timeout(500)
        page.screenshot(path=str(out / "screenshot.png"))
        if fly:
            expect(page.locator("#flight-status")).to_have_attribute(
                "data-status", "completed", timeout=120_000)
        phone = browser.new_page(viewport={"width": 390, "height": 844})
        phone.goto(url)
        phone.locator("#mission-list li").first.click()
        expect(phone.locator("#min-separation-value")).to_be_visible(timeout=60_000)
        if fly:
            phone.locator("#flight-list li[data-id]").first.click()
            expect(phone.locator("#time-label")).to_contain_text("replay")
        phone.evaluate("window.scrollTo(0, 0)")
        phone.wait_for_timeout(500)
        phone.screenshot(path=str(out / "screenshot-phone.png"))
        browser.close()


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), "--no-fly" not in sys.argv[3:])
