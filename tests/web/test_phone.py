"""Phone width (390x844): no sideways scroll, a one-line header, no blank screens before a
plan, and a replayed flight readable on the way down the page."""

from __future__ import annotations

from collections.abc import Callable

from playwright.sync_api import Page, expect

from tests.web.conftest import PHONE
from tests.web.support import CROSSING, assert_fits, fill_scenario, plan


def test_phone_width_fits_before_and_after_a_plan(open_page: Callable[..., Page]) -> None:
    page = open_page(PHONE)
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    header = page.locator("header").bounding_box()
    assert header and header["height"] <= 48  # one line: title, status, Abort
    assert_fits(page)
    # Before a plan: the note, then the form at once (no screens of empty plots).
    name = page.locator("#f-name").bounding_box()
    assert name and name["y"] < 844 * 0.6
    expect(page.locator("#plot3d")).to_be_hidden()

    fill_scenario(page, "phone", 50, CROSSING)
    plan(page)
    assert_fits(page)
    # The fly screen comes first on a narrow screen: map, then controls and fleet.
    top = page.evaluate("document.getElementById('fly-view').getBoundingClientRect().top"
                        " + window.scrollY")
    view = page.locator("#fly-view").bounding_box()
    assert view and view["width"] <= 390 and top < 300
    expect(page.locator("#fly-button")).to_be_enabled()
    page.locator("#fly-button").scroll_into_view_if_needed()
    expect(page.locator("#vehicle-state")).to_be_visible()
    header = page.locator("header").bounding_box()
    assert header and header["height"] <= 48
    assert_fits(page)
