"""The fly screen at 1440x900 while mock vehicles fly: the top-down view with labelled live
icons, planned paths and trails, the fleet table with health colours beside it, the progress
bar on the plan's time slider following the flight, a clamped clock once the plan is flown,
pause/resume of the flight itself, per-vehicle commands (answered through routes, see
test_controls_and_health), and Abort from anywhere."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import httpx
from playwright.sync_api import Page, expect

from tests.api.support import ServiceProcess
from tests.web.support import (
    CROSSING,
    CROSSING_HORIZON_S,
    CROSSING_STEPS,
    fill_scenario,
    plan,
    planned_api,
)

ICON_LABEL = re.compile(r"^([a-d]) (-?\d+\.\d) m$")
#: The plan's horizon as the clock shows it ("6.0").
HORIZON = f"{CROSSING_HORIZON_S:.1f}"


def test_fly_screen_follows_the_flight_then_abort(
    open_page: Callable[..., Page], service: ServiceProcess
) -> None:
    sent: list[tuple[str, Any]] = []
    page = open_page(before=lambda p: planned_api(p, service, sent))
    expect(page.locator("#service-status")).to_contain_text("4 mock vehicles")
    fill_scenario(page, "browser-flight", CROSSING_STEPS, CROSSING)
    mission_id = plan(page)
    expect(page.locator("#pause-button")).to_be_disabled()  # nothing flying yet
    expect(page.locator("#mapping-pairs")).to_have_text("a→mock 1, b→mock 2, c→mock 3, d→mock 4")
    expect(page.locator("#flight-list")).to_contain_text("not flown yet")

    # Every clock text the page shows, kept by the page itself (no race with the test). At the
    # first clock update while the plan is between 15 % and 85 % flown, the page itself takes
    # one reading and clicks Pause in the same moment: the checks below then read a fleet that
    # holds still, however slowly a busy machine lets the test run.
    page.evaluate("""() => { window.clockTexts = []; window.midPlan = null;
        const label = document.getElementById('time-label');
        new MutationObserver(() => {
            window.clockTexts.push(label.textContent);
            const progress = document.getElementById('flight-progress').value;
            const pause = document.getElementById('pause-button');
            if (window.midPlan || progress < 150 || progress > 850 || pause.disabled) return;
            window.midPlan = {slider: Number(document.getElementById('time-slider').value),
                progress, label: label.textContent,
                icons: Array.from(document.querySelectorAll('#fly-view g.vehicle-icon text'),
                                  (t) => t.textContent)};
            pause.click();
        }).observe(label, {childList: true, characterData: true, subtree: true}); }""")
    page.click("#fly-button")
    status = page.locator("#flight-status")
    # Running, or already paused by the page's own mid-plan click.
    expect(status).to_have_attribute("data-status", re.compile("^(running|paused)$"),
                                     timeout=30_000)
    expect(page.locator("#fly-button")).to_be_disabled()
    expect(page.locator("#flight-list li[data-id]")).to_have_count(1)
    expect(page.locator("#flight-list .status-badge.live")).to_have_count(1)
    # One screen: the top-down view and the whole fleet table, together, without scrolling.
    expect(page.locator("#fly-view")).to_be_in_viewport(ratio=1)
    expect(page.locator("#vehicle-state")).to_be_in_viewport(ratio=1)
    view = page.locator("#fly-view").bounding_box()
    table = page.locator("#vehicle-state").bounding_box()
    assert view and table and table["x"] >= view["x"] + view["width"]  # docked beside it

    # Mid-plan: the slider follows flight time and the bar fills with it (the page's one
    # reading, taken as it clicked Pause).
    now = page.wait_for_function("window.midPlan", timeout=90_000).json_value()
    reading = re.search(rf"t = (\d+\.\d) s of {re.escape(HORIZON)} s", now["label"])
    assert reading, now["label"]
    flight_time = float(reading.group(1))
    assert now["slider"] == round(flight_time * 10)  # trajectory sampled at 10 Hz
    # the clock shows tenths of a second: the bar may differ by what half a tenth is of the
    # horizon, plus its own rounding to a whole per mille
    assert abs(now["progress"] - 1000 * flight_time / CROSSING_HORIZON_S) <= \
        1000 * 0.05 / CROSSING_HORIZON_S + 1
    # Live icons: one per vehicle, labelled with id and altitude.
    parsed = [ICON_LABEL.match(text) for text in now["icons"]]
    labels = [m for m in parsed if m]
    assert len(labels) == len(parsed), now["icons"]
    assert sorted(m.group(1) for m in labels) == ["a", "b", "c", "d"]
    assert all(0.1 < float(m.group(2)) <= 3.0 for m in labels), now  # airborne, in the box
    expect(page.locator("#fly-view polyline.planned-path")).to_have_count(4)
    expect(page.locator("#fly-view polyline.trail")).to_have_count(4)
    expect(page.locator("#fly-view circle.planned-icon")).to_have_count(4)
    # The fleet table: live link, mode and arming, with health colours.
    rows = page.locator("#vehicle-state tbody tr")
    expect(rows).to_have_count(4)
    expect(page.locator('#vehicle-state td[data-key="link"].cell-ok')).to_have_count(4)
    expect(rows.first.locator('td[data-key="mode"]')).to_have_text("OFFBOARD")
    expect(rows.first.locator('td[data-key="armed"]')).to_have_text("armed")
    # The 3-D view shows the live positions too, labelled.
    flown = page.evaluate("document.getElementById('plot3d').data.at(-1).text")
    assert sorted(flown) == ["a", "b", "c", "d"]
    # The view lies below the fly screen, so its scene is redrawn only once it is scrolled
    # into view: then it draws them (plotly's drawn data, `_fullData`).
    page.locator("#plot3d").scroll_into_view_if_needed()
    page.wait_for_function("""() => { const drawn = document.getElementById('plot3d')._fullData;
        return drawn && [...drawn.at(-1).text].sort().join() === 'a,b,c,d'; }""")
    # Pause and resume go to this flight; per-vehicle commands from the vehicle's row.
    flight_id = status.inner_text().split(":")[0].removeprefix("flight ").strip()
    # The service's answers may be slow on a busy machine: awaited, not timed.
    expect(page.locator("#command-result")).to_have_text("paused", timeout=30_000)
    expect(page.locator("#resume-button")).to_be_enabled()
    expect(page.locator("#pause-button")).to_be_disabled()
    expect(status).to_have_attribute("data-status", "paused")  # the service paused it
    page.click("#resume-button")
    expect(page.locator("#command-result")).to_have_text("resumed", timeout=30_000)
    expect(page.locator("#pause-button")).to_be_enabled()
    expect(page.locator("#resume-button")).to_be_disabled()
    expect(status).to_have_attribute("data-status", "running")
    page.locator('#vehicle-state tr[data-id="c"] button[data-vehicle-command="land"]').click()
    # answered once the vehicle acknowledged LAND: awaited like pause and resume
    expect(page.locator("#command-result")).to_have_text("land sent to c", timeout=30_000)
    assert sent == [(f"/api/flights/{flight_id}/pause", None),
                    (f"/api/flights/{flight_id}/resume", None),
                    ("/api/vehicles/c/commands", {"command": "land", "confirm": True})]

    expect(status).to_have_attribute("data-status", "completed", timeout=90_000)
    # Past the plan's end (holding, landing) the clock stopped at the horizon: never "t = 9
    # s of 6 s"; the bar full.
    clocks = page.evaluate("window.clockTexts")
    assert any(f"plan flown ({HORIZON} s of {HORIZON} s), +" in c for c in clocks), clocks[-5:]
    for c in clocks:
        assert all(float(t) <= CROSSING_HORIZON_S for t in re.findall(r"t = (\d+\.\d)", c)), c
    assert page.evaluate("document.getElementById('flight-progress').value") == 1000
    expect(page.locator("#flight-summary")).to_contain_text("completed: yes")
    expect(page.locator("#event-log")).to_contain_text("flight_start")
    clock = page.locator("#time-label").inner_text()
    assert all(float(t) <= CROSSING_HORIZON_S for t in re.findall(r"t = (\d+\.\d)", clock)), clock
    expect(page.locator("#flight-list .status-badge.good")).to_have_text("completed")
    expect(page.locator("#fly-button")).to_be_enabled()
    record = httpx.get(f"{service.base_url}/api/flights/{flight_id}").json()
    assert record["status"] == "completed" and record["mission_id"] == mission_id

    # Fly again and abort from the always-visible button while the fleet is in the air: the
    # page presses it the moment its clock first reads "flying" (a busy machine could let the
    # short flight end between the test seeing that and its own click).
    page.evaluate("""() => { const label = document.getElementById('time-label');
        const watch = new MutationObserver(() => {
            if (!label.textContent.startsWith('flying')) return;
            watch.disconnect();
            document.getElementById('abort-button').click();
        });
        watch.observe(label, {childList: true, characterData: true, subtree: true}); }""")
    page.click("#fly-button")
    page.mouse.move(200, 600)
    page.mouse.wheel(0, 5000)  # the editor scrolled away: the header (and Abort) stays
    expect(page.locator("#abort-button")).to_be_in_viewport()
    # nothing covers it: a pointer at its centre lands on the button itself
    assert page.evaluate("""() => { const b = document.getElementById('abort-button');
        const r = b.getBoundingClientRect();
        return document.elementFromPoint(r.x + r.width / 2, r.y + r.height / 2) === b; }""")
    expect(status).to_have_attribute("data-status", "aborted", timeout=60_000)
    expect(page.locator("#event-log")).to_contain_text("abort")
    # The summary tells the tracking before the abort from the landing after it.
    expect(page.locator("#flight-summary")).to_contain_text(re.compile(
        r"tracking error max [\d.]+ m up to the abort at t = [\d.]+ s, then [\d.]+ s aborting"))
    expect(page.locator("#flight-banner")).to_have_text("")
    expect(page.locator("#flight-list li[data-id]")).to_have_count(2)
    aborted = page.locator('#flight-list li[data-status="aborted"] .status-badge.poor')
    expect(aborted).to_be_visible()
    vehicles = httpx.get(f"{service.base_url}/api/vehicles").json()
    assert vehicles["fleet"]["flying"] is None
