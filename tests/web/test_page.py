"""The browser page in a real browser: fill the form, plan, read the plots and the separation
figure, see validation errors next to the fields, place points on the top view."""

from __future__ import annotations

import httpx
from playwright.sync_api import Page, expect

from planner import Plan
from tests.api.support import ServiceProcess, example
from tests.web.support import CROSSING, fill_scenario, plan, shown_mission_id

#: Each plot's toolbar (plotly's modebar) and caption boxes, and whether they overlap.
TOOLBAR_OVER_CAPTION = """(id) => {
  const plot = document.getElementById(id);
  const box = (sel) => plot.querySelector(sel)?.getBoundingClientRect();
  const bar = box(".modebar"), cap = box(".gtitle");
  if (!bar || !cap) return "missing";
  return bar.left < cap.right && cap.left < bar.right && bar.top < cap.bottom
    && cap.top < bar.bottom;
}"""


def test_plan_from_the_form_shows_plots_and_separation(
    page: Page, service: ServiceProcess
) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)  # preset loaded
    fill_scenario(page)
    expect(page.locator("#top-view circle")).to_have_count(4)
    page.click("#plan-button")
    expect(page.locator("#min-separation-value")).to_be_visible(timeout=60_000)
    expect(page.locator("#plan-state")).to_contain_text("converged")

    mission_id = page.locator("#mission-title").inner_text().split("·")[1].strip()
    mission = httpx.get(f"{service.base_url}/api/missions/{mission_id}").json()
    assert mission["scenario"]["name"] == "browser-swap"
    assert [v["id"] for v in mission["scenario"]["vehicles"]] == ["a", "b", "c", "d"]
    verification = mission["plan"]["verification"]

    # The progress log listed the SCP iterations as they came.
    iterations = len(mission["plan"]["iterations"])
    expect(page.locator("#progress-log li")).to_have_count(iterations)
    # 3-D view: one line per vehicle, plus the "now" and "flown" marker traces.
    traces = page.evaluate("document.getElementById('plot3d').data.map(t => t.name)")
    assert traces[:4] == ["a", "b", "c", "d"] and len(traces) == 6
    assert page.locator("#plot3d canvas").count() > 0  # WebGL scene drawn
    # The separation figure: minimum pairwise distance over time against R.
    shown = float(page.locator("#min-separation-value").get_attribute("data-value") or "nan")
    assert shown == verification["min_separation_continuous"]
    sampled_min = float(page.locator("#separation-plot").get_attribute("data-minimum") or "nan")
    assert verification["min_separation_continuous"] - 1e-6 <= sampled_min
    assert sampled_min >= 1.0 - 1e-3  # never closer than R at the samples
    sep = page.evaluate("document.getElementById('separation-plot').data"
                        ".map(t => ({name: t.name, n: t.y.length, y0: t.y[0]}))")
    assert sep[1]["name"] == "R = 1 m" and sep[1]["y0"] == 1.0
    assert sep[0]["n"] == 401  # 20 s at 20 Hz, both ends
    title = page.locator("#separation-plot .gtitle").text_content() or ""
    assert "minimum pairwise separation" in title
    for plot in ("#speed-plot", "#thrust-plot"):
        assert page.evaluate(f"document.querySelector('{plot}').data.length") >= 4
    expect(page.locator("#verification")).to_contain_text("within bounds")
    expect(page.locator("#solver-figures")).to_contain_text("SCP iterations")
    # The time slider moves the vehicles along their paths.
    slider = page.locator("#time-slider")
    slider.fill("100")
    expect(page.locator("#time-label")).to_contain_text("t = 10.0 s of 20.0 s")
    expect(page.locator("#mission-list li").first).to_contain_text("browser-swap")


def test_a_plan_whose_progress_stream_was_missed_still_lists_every_iteration(
    page: Page, service: ServiceProcess
) -> None:
    """A plan that ends before the page follows its stream (a quick plan, a busy browser):
    the progress log is completed from the plan's own iteration record."""
    page.route("**/api/missions/*/events", lambda route: route.abort())
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    fill_scenario(page, "browser-missed-stream", 50, CROSSING)  # a quick plan
    page.click("#plan-button")
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    mission_id = page.locator("#mission-title").inner_text().split("·")[1].strip()
    mission = httpx.get(f"{service.base_url}/api/missions/{mission_id}").json()
    iterations = mission["plan"]["iterations"]
    log = page.locator("#progress-log li")
    expect(log).to_have_count(len(iterations))
    expect(log.last).to_contain_text(f"iteration {iterations[-1]['iteration']}:")


def test_validation_errors_appear_next_to_the_field(page: Page) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    page.fill('input[data-field="vehicles[2].goal[0]"]', "9")  # outside the 5 m box
    page.click("#plan-button")
    error_row = page.locator("#vehicle-table tr.vehicle:nth-of-type(3) + tr.error-row")
    expect(error_row).to_contain_text("vehicles[2].goal")
    expect(error_row).to_contain_text("outside the workspace")
    goal_x = page.locator('input[data-field="vehicles[2].goal[0]"]')
    expect(goal_x).to_have_class("invalid")
    expect(page.locator('input[data-field="vehicles[1].goal[0]"]')).not_to_have_class("invalid")
    # A top-level field's error goes to that field.
    page.fill('input[data-field="vehicles[2].goal[0]"]', "4")
    page.fill("#f-dt", "-1")
    page.click("#plan-button")
    expect(page.locator('[data-error-for~="dt"]')).to_contain_text("dt: must be positive")
    expect(page.locator("#f-dt")).to_have_class("invalid")
    expect(page.locator("tr.error-row")).to_have_count(0)


def test_top_view_click_places_the_selected_vehicle(page: Page) -> None:
    scenario = example("paper-circle4")
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    page.locator("#vehicle-table tr.vehicle").nth(1).click()  # select uav2
    view = page.locator("#top-view")
    box = view.bounding_box()
    assert box is not None
    # The 5 m x 5 m workspace spans SVG 20..380 (of 400) in both axes, y up.
    def click_world(x: float, y: float) -> None:
        sx = (20 + x / 5 * 360) / 400 * box["width"]
        sy = (380 - y / 5 * 360) / 400 * box["height"]
        view.click(position={"x": sx, "y": sy})

    click_world(1.0, 4.0)  # start ...
    click_world(4.0, 1.0)  # ... then the goal, automatically
    start = [float(page.input_value(f'input[data-field="vehicles[1].start[{a}]"]'))
             for a in range(3)]
    goal = [float(page.input_value(f'input[data-field="vehicles[1].goal[{a}]"]'))
            for a in range(3)]
    assert abs(start[0] - 1.0) < 0.03 and abs(start[1] - 4.0) < 0.03
    assert abs(goal[0] - 4.0) < 0.03 and abs(goal[1] - 1.0) < 0.03
    assert start[2] == scenario["vehicles"][1]["start"][2]  # height kept
    # Other vehicles untouched.
    assert float(page.input_value('input[data-field="vehicles[0].start[0]"]')) == 4.5


def test_the_page_keeps_no_copy_of_the_status_sets() -> None:
    """Mission and flight statuses come from GET /api/status (`statuses`), not from
    literals in the page's scripts."""
    import re
    from pathlib import Path

    web = Path(__file__).resolve().parents[2] / "web"
    literals = re.compile(r"""status\s*[!=]==?\s*["'](planning|planned|failed|starting|running|"""
                          r"""aborting|completed|incomplete|aborted|interrupted)["']""")
    found = [(p.name, m.group(0)) for p in sorted(web.glob("*.js"))
             for m in literals.finditer(p.read_text())]
    assert found == []


def test_the_method_selector_defaults_to_auto_and_the_plan_panel_names_the_method(
    page: Page, service: ServiceProcess
) -> None:
    """The form's method selector starts at auto and writes the scenario's `method`; the
    plan panel says which method planned (and what became of a raced one)."""
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    selector = page.locator("#f-method")
    expect(selector).to_have_value("auto")
    assert page.locator("#f-method option").all_inner_texts() == [
        "auto", "whole fleet", "prioritized batches"]
    fill_scenario(page, "browser-method", 50, CROSSING)
    page.click("#plan-button")
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    first = shown_mission_id(page)
    mission = httpx.get(f"{service.base_url}/api/missions/{first}").json()
    assert mission["scenario"]["method"] == "auto"
    expect(page.locator("#plan-method")).to_contain_text(mission["plan"]["method"])
    selector.select_option("prioritized")
    page.click("#plan-button")
    expect(page.locator("#mission-title")).not_to_contain_text(first, timeout=60_000)
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    mission = httpx.get(f"{service.base_url}/api/missions/"
                        f"{shown_mission_id(page)}").json()
    assert mission["scenario"]["method"] == "prioritized"
    assert mission["plan"]["method"] == "prioritized"
    # The plan's cost over every batch, not the last batch's (its last iteration's).
    cost = Plan.from_dict(mission["plan"]).cost
    assert abs(cost - mission["plan"]["iterations"][-1]["cost"]) > 1.0
    page.wait_for_function("(cost) => Math.abs(Number(document.getElementById('final-cost')"
                           "?.textContent) - cost) <= 0.006", arg=cost)


def test_no_plot_toolbar_covers_its_caption_on_a_desktop_or_a_phone(page: Page) -> None:
    """plotly's toolbar (top right) has a row of its own above each plot's caption."""
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    fill_scenario(page, "browser-captions", 50, CROSSING)
    plan(page)
    plots = ("plot3d", "separation-plot", "speed-plot", "thrust-plot")
    for width in (1280, 390):
        page.set_viewport_size({"width": width, "height": 900})
        for plot in plots:
            page.wait_for_function(f"document.querySelector('#{plot} .gtitle') !== null")
            assert page.evaluate(TOOLBAR_OVER_CAPTION, plot) is False, (plot, width)
