"""The page's obstacles in a real browser: a preset's pillar drawn on the top view and in the
3-D plan, a box added by its button, dragged and sized in its fields, sent with the plan, and
a box on a vehicle's goal refused with that box marked in its row and on the map."""

from __future__ import annotations

import re

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.api.support import ServiceProcess
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
