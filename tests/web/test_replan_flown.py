"""A replan flown from the page on the service's mock fleet: a goal dragged on the fly view,
a vehicle dropped from the fleet table, then the goal sent; the page shows each replan switched, the
new plan drawn (the path and the goal marker at the new goal, the dropped vehicle's row),
the flight completes, and reopened later it is replayed against the plans it flew."""

from __future__ import annotations

import json
import re
from collections.abc import Callable

import pytest
from playwright.sync_api import Page, Route, expect
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from gcs import phases
from tests.api.support import ServiceProcess
from tests.web.conftest import FLY_OPTIONS, FLY_REQUEST
from tests.web.support import CROSSING, PAD, SCALE, VIEW, client_point, fill_scenario, plan

pytestmark = pytest.mark.skipif(not hasattr(phases, "ReplanStatus"),
                                reason="needs FlightExecutor.replan (wt/flight)")
#: Where b's goal is dragged to (x, y; its height is kept).
NEW_GOAL = (1.0, 1.4)


def _with_lead(route: Route) -> None:
    """The page's Fly with the browser tests' options and a replan lead that a busy machine
    plans within (the flight's own bound is tested in tests/flight)."""
    if route.request.method != "POST":
        route.fallback()
        return
    assert route.request.post_data is None  # the page sends no options
    route.continue_(post_data=json.dumps({**FLY_OPTIONS, "replan_lead_s": 3.0}),
                    headers={**route.request.headers, "content-type": "application/json"})


def _last_point(page: Page, vid: str) -> tuple[float, float]:
    points = page.locator(f'#fly-view polyline.planned-path[data-id="{vid}"]').get_attribute(
        "points")
    assert points
    x, y = points.split()[-1].split(",")
    return float(x), float(y)


def test_a_goal_dragged_and_a_vehicle_dropped_are_flown(
    open_page: Callable[..., Page], service: ServiceProcess
) -> None:
    page = open_page(before=lambda p: p.route(FLY_REQUEST, _with_lead))
    fill_scenario(page, "replan-flown", 100, CROSSING)  # 20 s
    mission_id = plan(page)
    page.click("#fly-button")
    expect(page.locator("#time-label")).to_contain_text(re.compile(r"flying · t = \d"),
                                                        timeout=120_000)

    # b's goal dragged (and its x, y typed), kept in the panel while d is dropped.
    marker = page.locator('#fly-view circle.goal-marker[data-id="b"]')
    box = marker.bounding_box()
    assert box is not None
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(*client_point(page, *NEW_GOAL), steps=8)
    page.mouse.up()
    page.fill('#replan-goals input[data-field="goals.b[0]"]', str(NEW_GOAL[0]))
    page.fill('#replan-goals input[data-field="goals.b[1]"]', str(NEW_GOAL[1]))
    expect(page.locator("#replan-send")).to_be_enabled()
    # The page sends the goals the moment the drop has switched (a replan runs one at a
    # time; a busy machine could otherwise let the replanned, shorter flight end first).
    page.evaluate("""() => { const status = document.getElementById('replan-status');
        const watch = new MutationObserver(() => {
            if (!status.textContent.startsWith('replan 1: switched')) return;
            watch.disconnect();
            document.getElementById('replan-send').click();
        });
        watch.observe(status, {childList: true, characterData: true, subtree: true}); }""")

    # Drop d (to land) from its row. The row's button is the same element across the table's
    # telemetry redraws (a press and its release on one element: a click is never lost to a
    # redraw between them).
    row = '#vehicle-state tr[data-id="d"]'
    page.evaluate(f"""() => {{ window.dropButton = document.querySelector('{row} button');
        window.altCell = document.querySelector('{row} td[data-key="alt"]'); }}""")
    page.wait_for_function(f"""document.querySelector('{row} td[data-key="alt"]')
                               !== window.altCell""", timeout=30_000)  # the row redrawn
    assert page.evaluate(f"document.querySelector('{row} button') === window.dropButton")
    page.locator(f'{row} td[data-key="replan"] button').click()
    status = page.locator("#replan-status")
    expect(page.locator('#vehicle-state tr[data-id="d"] td[data-key="replan"]')).to_have_text(
        "dropped", timeout=60_000)
    answered = ("document.querySelector('#replan-status').textContent.startsWith('replan 2')"
                " || document.querySelector('#replan-error').textContent !== ''")
    try:
        page.wait_for_function(answered, timeout=60_000)
    except PlaywrightTimeout:
        pytest.fail(f"the goal replan was never sent or answered; status "
                    f"{status.inner_text()!r}")
    assert page.locator("#replan-error").inner_text() == ""
    expect(status).to_contain_text("replan 2: switched", timeout=60_000)
    expect(page.locator('#fly-view circle.goal-marker[data-id="d"]')).to_have_count(0)
    # The new plan drawn: b's path ends at its new goal, and so does its marker.
    want = (PAD + NEW_GOAL[0] * SCALE, VIEW - PAD - NEW_GOAL[1] * SCALE)
    # The status comes with the snapshot; the plans flown are fetched after it (and b's new
    # goal keeps its old x), so both coordinates are waited for.
    marker = page.locator('#fly-view circle.goal-marker[data-id="b"]')
    expect(marker).to_have_attribute("cy", re.compile(rf"^{int(want[1])}\."), timeout=30_000)
    expect(marker).to_have_attribute("cx", re.compile(rf"^{int(want[0])}\."))
    x, y = _last_point(page, "b")
    assert abs(x - want[0]) < 1 and abs(y - want[1]) < 1, (x, y, want)

    expect(page.locator("#flight-status")).to_have_attribute("data-status", "completed",
                                                                timeout=180_000)
    expect(page.locator("#replan-panel")).to_be_hidden()
    flight_id = page.locator("#flight-list li[data-id]").first.get_attribute("data-id")

    # Reopened later, the flight is replayed against the plans it flew (from its record).
    page.reload()
    page.locator(f'#mission-list li[data-id="{mission_id}"]').click()
    expect(page.locator("#fly-view polyline.planned-path")).to_have_count(4)
    x, y = _last_point(page, "b")
    assert abs(x - want[0]) > 5 or abs(y - want[1]) > 5  # the mission's own plan
    page.locator(f'#flight-list li[data-id="{flight_id}"]').click()
    expect(page.locator("#time-label")).to_contain_text(f"replay of flight {flight_id}")
    expect(page.locator('#fly-view polyline.planned-path[data-id="b"]')).to_have_attribute(
        "points", re.compile(rf" {int(want[0])}\.\d,{int(want[1])}\.\d$"))
