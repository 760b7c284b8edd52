"""The page's obstacles in a real browser: a preset's pillar drawn on the top view and in the
3-D plan, a box added by its button, dragged and sized in its fields, sent with the plan, and
a box on a vehicle's goal refused with that box marked in its row and on the map; boxes and
cylinders resized by their handles within bounds, by mouse and by a finger on a phone; a
prism moved."""

from __future__ import annotations

import json
import re
from collections.abc import Callable

import httpx
import pytest
from playwright.sync_api import Page, Route, expect

from tests.api.support import ServiceProcess
from tests.web.conftest import PHONE
from tests.web.support import plan

pytestmark = pytest.mark.browser

#: Every vehicle input's value, in the table's order.
VEHICLE_VALUES = "[...document.querySelectorAll('#vehicle-table input')].map(i => i.value)"


def _set_box(page: Page, index: int, lo: list[float], hi: list[float]) -> None:
    """Type a box's min and max into its fields."""
    for name, values in (("min", lo), ("max", hi)):
        for axis, value in enumerate(values):
            page.fill(f'input[data-field="obstacles[{index}].box.{name}[{axis}]"]', str(value))


def test_obstacles_are_drawn_edited_sent_and_marked_when_refused(
    page: Page, service: ServiceProcess
) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)  # first preset loaded
    page.select_option("#preset", "example:pillar-circle8")
    page.click("#preset-load")
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(8)
    expect(page.locator("#obstacle-table tr.obstacle")).to_have_count(1)
    # The pillar on the top view: its solid and its dashed clearance (R / 2 = 0.5 m wider).
    pillar = page.locator('#top-view g.obstacle[data-id="pillar"] circle')
    expect(pillar).to_have_count(2)
    r_solid, r_clear = (float(pillar.nth(k).get_attribute("r") or "nan") for k in (0, 1))
    assert r_clear == pytest.approx(r_solid * (0.3 + 0.5) / 0.3, rel=1e-3)

    page.click("#add-box")
    expect(page.locator("#obstacle-table tr.obstacle")).to_have_count(2)
    box = page.locator('#top-view g.obstacle[data-id="box2"] rect.solid')
    expect(box).to_have_count(1)
    min_x = page.locator('input[data-field="obstacles[1].box.min[0]"]')
    before = float(min_x.input_value())
    # Dragged to the right: its x fields follow, the vehicles stay.
    starts = page.evaluate(VEHICLE_VALUES)
    bb = box.bounding_box()
    assert bb is not None
    page.mouse.move(bb["x"] + bb["width"] / 2, bb["y"] + bb["height"] / 2)
    page.mouse.down()
    page.mouse.move(bb["x"] + bb["width"] / 2 + 30, bb["y"] + bb["height"] / 2, steps=4)
    page.mouse.up()
    assert float(min_x.input_value()) > before + 0.1
    assert page.evaluate(VEHICLE_VALUES) == starts

    # Sized in its fields, in a corner clear of every path; planned, the mission carries it.
    _set_box(page, 1, [0.0, 0.0, 0.0], [0.4, 0.4, 0.6])
    mission_id = plan(page)
    mission = httpx.get(f"{service.base_url}/api/missions/{mission_id}").json()
    sent = {o["id"]: o for o in mission["scenario"]["obstacles"]}
    assert sent["box2"]["box"] == {"min": [0.0, 0.0, 0.0], "max": [0.4, 0.4, 0.6]}
    assert sent["pillar"]["cylinder"]["radius"] == 0.3
    # The 3-D plan draws the obstacles: one mesh after the vehicles' lines and markers.
    traces = page.evaluate("document.getElementById('plot3d').data.map(t => [t.type, t.name])")
    assert traces[-1] == ["mesh3d", "obstacles"] and len(traces) == 8 + 3
    expect(page.locator('#fly-view g.obstacle[data-id="box2"]')).to_have_count(1)

    # On the first vehicle's goal: refused, the box marked in its row and on the map.
    goal = [float(page.input_value(f'input[data-field="vehicles[0].goal[{a}]"]')) for a in range(3)]
    _set_box(page, 1, [goal[0] - 0.2, goal[1] - 0.2, 0.0], [goal[0] + 0.2, goal[1] + 0.2, 3.0])
    page.click("#plan-button")
    box_row = page.locator("#obstacle-table tr.obstacle").nth(1)
    expect(box_row).to_have_class(re.compile(r"\bhas-error\b"))
    expect(page.locator('#top-view g.obstacle.invalid[data-id="box2"]')).to_have_count(1)
    expect(page.locator('#top-view g.obstacle.invalid[data-id="pillar"]')).to_have_count(0)
    expect(page.locator("#vehicle-table td.vehicle-error")).to_contain_text("box2")
    # Moving the box away clears the mark.
    page.fill('input[data-field="obstacles[1].box.min[0]"]', "0")
    expect(page.locator('#top-view g.obstacle.invalid')).to_have_count(0)


def _field(page: Page, path: str) -> float:
    """An obstacle field's value, as the table shows it."""
    return float(page.input_value(f'input[data-field="{path}"]'))


def _drag(page: Page, selector: str, dx: float, dy: float) -> None:
    """Press on the middle of `selector`, move by (dx, dy) screen pixels, release."""
    page.locator("#top-view").scroll_into_view_if_needed()  # the mouse acts in the viewport
    bb = page.locator(selector).bounding_box()
    assert bb is not None, selector
    x, y = bb["x"] + bb["width"] / 2, bb["y"] + bb["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + dx, y + dy, steps=4)
    page.mouse.up()


def _attrs(page: Page, selector: str, *names: str) -> list[float]:
    """Numeric attributes of one SVG element."""
    element = page.locator(selector)
    return [float(element.get_attribute(name) or "nan") for name in names]


def test_handles_resize_the_selected_box_and_cylinder_within_bounds(page: Page) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)  # first preset loaded
    page.select_option("#preset", "example:pillar-circle8")  # a 5 x 5 m workspace
    page.click("#preset-load")
    expect(page.locator("#obstacle-table tr.obstacle")).to_have_count(1)
    pillar = '#top-view g.obstacle[data-id="pillar"]'
    rim = f'{pillar} g.handle[data-handle="radius"]'
    expect(page.locator(rim)).to_have_count(0)  # handles only on the obstacle selected
    # Selected by a press on it (no move): its rim handle appears; dragged 30 px east, the
    # radius grows by those 30 px in metres and both circles follow.
    solid_px = page.locator(f"{pillar} circle.solid").bounding_box()
    assert solid_px is not None
    px_per_m = solid_px["width"] / (2 * 0.3)
    _drag(page, f"{pillar} circle.solid", 0, 0)
    expect(page.locator(rim)).to_have_count(1)
    (r_solid,) = _attrs(page, f"{pillar} circle.solid", "r")
    (r_clear,) = _attrs(page, f"{pillar} circle.clearance", "r")
    _drag(page, rim, 30, 0)
    radius = _field(page, "obstacles[0].cylinder.radius")
    assert radius == pytest.approx(0.3 + 30 / px_per_m, abs=0.03)
    assert _field(page, "obstacles[0].cylinder.center[0]") == 2.5  # the centre stays
    (r_solid_now,) = _attrs(page, f"{pillar} circle.solid", "r")
    (r_clear_now,) = _attrs(page, f"{pillar} circle.clearance", "r")
    assert r_solid_now == pytest.approx(r_solid * radius / 0.3, rel=1e-3)
    assert r_clear_now - r_solid_now == pytest.approx(r_clear - r_solid, abs=0.01)  # same clearance
    # Dragged far out: the circle stops at the workspace's side (2.5 m from its centre).
    _drag(page, rim, 400, 0)
    assert _field(page, "obstacles[0].cylinder.radius") == pytest.approx(2.5)
    # Dragged onto its centre: the radius stays positive (0.05 m at least).
    _drag(page, rim, -2.5 * px_per_m, 0)
    assert 0.05 <= _field(page, "obstacles[0].cylinder.radius") <= 0.1

    # A new box (selected): its max-x, max-y corner dragged 40 px right and 20 px up.
    page.click("#add-box")
    box = '#top-view g.obstacle[data-id="box2"]'
    corner = f'{box} g.handle[data-handle="max,max"]'
    expect(page.locator(f"{box} g.handle")).to_have_count(4)
    expect(page.locator(rim)).to_have_count(0)
    lo = [_field(page, f"obstacles[1].box.min[{a}]") for a in range(2)]
    hi = [_field(page, f"obstacles[1].box.max[{a}]") for a in range(2)]
    solid = _attrs(page, f"{box} rect.solid", "x", "y", "width", "height")
    clear = _attrs(page, f"{box} rect.clearance", "x", "y", "width", "height")
    _drag(page, corner, 40, -20)
    grown = [_field(page, f"obstacles[1].box.max[{a}]") for a in range(2)]
    assert grown[0] == pytest.approx(hi[0] + 40 / px_per_m, abs=0.03)
    assert grown[1] == pytest.approx(hi[1] + 20 / px_per_m, abs=0.03)
    assert [_field(page, f"obstacles[1].box.min[{a}]") for a in range(2)] == lo  # min corner stays
    # Its rectangle and its dashed clearance are redrawn to the new size, the margin kept.
    solid_now = _attrs(page, f"{box} rect.solid", "x", "y", "width", "height")
    clear_now = _attrs(page, f"{box} rect.clearance", "x", "y", "width", "height")
    assert solid_now[0] == pytest.approx(solid[0], abs=0.1)  # the left side stays
    assert solid_now[2] == pytest.approx(solid[2] * (grown[0] - lo[0]) / (hi[0] - lo[0]), rel=1e-3)
    assert solid_now[3] == pytest.approx(solid[3] * (grown[1] - lo[1]) / (hi[1] - lo[1]), rel=1e-3)
    for k in range(4):  # the clearance rectangle: the solid's, grown by the same margin
        assert clear_now[k] - solid_now[k] == pytest.approx(clear[k] - solid[k], abs=0.1)
    # Dragged past the opposite corner: clamped to the smallest box (0.1 m), not inverted.
    _drag(page, corner, -6 * px_per_m, 6 * px_per_m)
    assert _field(page, "obstacles[1].box.max[0]") == pytest.approx(lo[0] + 0.1)
    assert _field(page, "obstacles[1].box.max[1]") == pytest.approx(lo[1] + 0.1)
    # The opposite corner dragged out of the map: stopped at the workspace's corner (0, 0).
    _drag(page, f'{box} g.handle[data-handle="min,min"]', -400, 400)
    assert [_field(page, f"obstacles[1].box.min[{a}]") for a in range(2)] == [0.0, 0.0]
    assert _field(page, "obstacles[1].box.max[0]") == pytest.approx(lo[0] + 0.1)


#: A triangular prism added to the pillar example the page loads (tests only: no example
#: ships one), in a corner of its 5 x 5 m workspace.
HUT_POLYGON = [[0.2, 0.2], [0.8, 0.2], [0.5, 0.7]]
HUT = {"id": "hut", "prism": {"polygon": HUT_POLYGON, "z": [0.0, 1.0]}}


def _with_hut(page: Page) -> None:
    def answer(route: Route) -> None:
        scenario = httpx.get(route.request.url).json()
        scenario["obstacles"].append(HUT)
        route.fulfill(status=200, content_type="application/json", body=json.dumps(scenario))

    page.route("**/api/examples/pillar-circle8", answer)


def _px_per_m(page: Page) -> float:
    """Screen pixels per metre on the top view of a 5 m workspace (360 of its 400 units)."""
    view = page.locator("#top-view").bounding_box()
    assert view is not None
    return view["width"] * 360 / 400 / 5


def test_a_prism_moves_by_dragging_and_has_no_handles(open_page: Callable[..., Page]) -> None:
    page = open_page(before=_with_hut)
    page.select_option("#preset", "example:pillar-circle8")
    page.click("#preset-load")
    expect(page.locator("#obstacle-table tr.obstacle")).to_have_count(2)
    hut = '#top-view g.obstacle[data-id="hut"]'
    row = page.locator("#obstacle-table tr.obstacle").nth(1)
    points = page.locator(f"{hut} polygon.solid").get_attribute("points")
    px = _px_per_m(page)
    _drag(page, f"{hut} polygon.solid", 0.5 * px, -0.25 * px)  # 0.5 m east, 0.25 m north
    expect(page.locator(f"{hut}.selected")).to_have_count(1)
    expect(page.locator(f"{hut} g.handle")).to_have_count(0)  # moved only, not resized
    moved = json.loads(row.get_attribute("data-polygon") or "[]")
    for (x, y), (x0, y0) in zip(moved, HUT_POLYGON, strict=True):
        assert (x - x0, y - y0) == (pytest.approx(0.5, abs=0.03), pytest.approx(0.25, abs=0.03))
    assert page.locator(f"{hut} polygon.solid").get_attribute("points") != points
    assert _field(page, "obstacles[1].prism.z[1]") == 1.0  # heights stay


def test_a_finger_resizes_a_box_on_a_phone_without_scrolling(
    open_page: Callable[..., Page]
) -> None:
    page = open_page(PHONE, has_touch=True)
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)  # first preset loaded
    page.click("#add-box")  # 1 m wide, selected
    box = '#top-view g.obstacle[data-id="box1"]'
    corner = page.locator(f'{box} g.handle[data-handle="max,max"]')
    corner.scroll_into_view_if_needed()
    solid = page.locator(f"{box} rect.solid").bounding_box()
    bb = corner.bounding_box()
    assert solid is not None and bb is not None
    high = _field(page, "obstacles[0].box.max[1]")
    x, y = bb["x"] + bb["width"] / 2, bb["y"] + bb["height"] / 2
    scrolled = page.evaluate("window.scrollY")
    # A finger on the corner moving 40 px up (which elsewhere scrolls the page): touch events
    # as a phone sends them, through the DevTools protocol.
    cdp = page.context.new_cdp_session(page)
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [{"x": x, "y": y}]})
    for k in range(1, 6):
        cdp.send("Input.dispatchTouchEvent",
                 {"type": "touchMove", "touchPoints": [{"x": x, "y": y - 8 * k}]})
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
    assert _field(page, "obstacles[0].box.max[1]") == pytest.approx(
        high + 40 / solid["width"], abs=0.03)  # the box grew north by the 40 px
    assert page.evaluate("window.scrollY") == scrolled  # and the page stayed put
