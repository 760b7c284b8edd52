"""The fly screen says what it means: the closest pair now beside the closest so far, event
lines that do not say a word twice, a play glyph that every font draws (SVG), and Fly
scrolled to below the sticky header rather than under it."""

from __future__ import annotations

from collections.abc import Callable

from playwright.sync_api import Page, expect

from tests.web.conftest import PHONE
from tests.web.support import plan


def test_event_lines_do_not_repeat_a_word(page: Page) -> None:
    texts = page.evaluate("""async () => {
        const { eventText } = await import("/flight.js");
        return [
            eventText({kind: "landed", detail: "landed and disarmed"}),
            eventText({kind: "land", detail: "landing"}),
            eventText({kind: "flight_start", detail: "flight start at tick 3"}),
            eventText({kind: "mode", detail: "OFFBOARD"}),
            eventText({kind: "armed", detail: ""}),
        ];
    }""")
    assert texts == ["landed and disarmed", "landing", "flight start at tick 3",
                     "mode: OFFBOARD", "armed"]


def test_the_closest_pair_now_is_told_apart_from_the_closest_so_far(page: Page) -> None:
    line = page.evaluate("""async () => {
        const { separationLine } = await import("/flight.js");
        return separationLine({min_separation_live: 1.0, vehicles: [
            {id: "a", position: [0, 0, 1]}, {id: "b", position: [3, 4, 1]},
            {id: "c"}]});
    }""")
    assert line == "closest pair now 5.00 m · closest so far 1.00 m"


def test_the_play_glyph_is_drawn_not_a_font_character(page: Page) -> None:
    plan(page)
    button = page.locator("#play")
    expect(button).to_have_attribute("data-icon", "play")
    expect(button.locator("svg path")).to_have_count(1)
    button.click()
    expect(button).to_have_attribute("data-icon", "pause")
    expect(button.locator("svg rect")).to_have_count(2)
    assert button.inner_text().strip() == ""  # no glyph a font may lack
    button.click()
    expect(button).to_have_attribute("data-icon", "play")


def test_fly_scrolled_to_stays_below_the_header_on_a_phone(
        open_page: Callable[..., Page]) -> None:
    page = open_page(PHONE)
    plan(page)
    page.evaluate("window.scrollTo(0, document.body.scrollHeight)")
    page.evaluate("document.getElementById('fly-screen').scrollIntoView({block: 'nearest'})")
    header = page.locator("header").bounding_box()
    fly = page.locator("#fly-screen").bounding_box()
    assert header and fly
    assert fly["y"] >= header["y"] + header["height"]


def test_a_settling_estimator_is_not_shown_as_a_pre_arm_failure(page: Page) -> None:
    cells = page.evaluate("""async () => {
        const { healthCell } = await import("/health.js");
        const h = (warnings) => ({unhealthy: [], prearm_ok: false, warnings});
        return [
            healthCell(h([])),
            healthCell(h(["Preflight Fail: heading estimate not stable",
                          "Arming denied: Resolve system health failures first"])),
            healthCell(h(["Preflight Fail: No valid data from Baro 0"])),
            healthCell({unhealthy: ["3D gyro"], prearm_ok: false, warnings: []}),
        ].map(([text, level]) => [text, level]);
    }""")
    assert cells == [["pre-arm not ready", "warn"], ["estimator settling", "warn"],
                     ["No valid data from Baro 0", "bad"], ["3D gyro", "bad"]]


def test_the_fleet_table_shows_every_column_at_phone_width(
        open_page: Callable[..., Page]) -> None:
    page = open_page(PHONE)
    plan(page)
    table = page.locator("#vehicle-state")
    expect(table.locator("th", has_text="phase")).to_have_count(1)
    widths = page.evaluate("""() => {
        const table = document.querySelector('#vehicle-state');
        return [table.scrollWidth, table.closest('.table-wrap').clientWidth];
    }""")
    assert widths[0] <= widths[1], widths  # no column behind the table's own scroller
