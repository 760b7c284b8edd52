"""The page is ready when it looks ready: Plan stays disabled until the page holds the
service's status sets and the first preset, then a Plan clicked at once sends that whole
scenario; the 3.5 MB plotly.js is fetched only once a plan is asked for."""

from __future__ import annotations

from collections.abc import Callable

from playwright.sync_api import Page, Request, Route, expect

from tests.api.support import ServiceProcess, example


def test_plan_clicked_as_soon_as_enabled_sends_the_whole_preset(
    open_page: Callable[..., Page], service: ServiceProcess
) -> None:
    urls: list[str] = []
    page = open_page(before=lambda p: p.on("request", lambda r: urls.append(r.url)))
    plan_button = page.locator("#plan-button")
    expect(plan_button).to_be_enabled()
    assert not any(u.endswith("/vendor/plotly.min.js") for u in urls)  # not before Plan
    with page.expect_request(lambda r: r.method == "POST" and "/api/missions" in r.url) as sent:
        plan_button.click()
    request: Request = sent.value
    body = request.post_data_json
    assert body is not None
    preset = example("paper-circle4")
    assert body["limits"]["position_min"] == preset["limits"]["position_min"]
    assert [v["id"] for v in body["vehicles"]] == [v["id"] for v in preset["vehicles"]]
    answer = request.response()
    assert answer is not None and answer.status in (201, 202), answer and answer.text()
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    expect(page.locator("#plan-state")).not_to_contain_text("rejected")
    expect(page.locator("#form-error")).to_have_text("")
    expect(page.locator("#min-separation-value")).to_be_visible(timeout=30_000)  # drawn
    assert any(u.endswith("/vendor/plotly.min.js") for u in urls)  # the 3-D view needs it
    assert page.evaluate("document.getElementById('plot3d').data.length") == 6


def test_plan_waits_for_the_service_status(open_page: Callable[..., Page]) -> None:
    held: list[Route] = []

    def hold(p: Page) -> None:
        p.route("**/api/status", lambda route: held.append(route))

    page = open_page(before=hold)
    # The form is filled and usable while the status is on its way; Plan is not.
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    page.wait_for_function("document.querySelectorAll('#preset-examples option').length > 0")
    expect(page.locator("#plan-button")).to_be_disabled()
    expect(page.locator("#sequence-plan")).to_be_disabled()
    expect(page.locator("#preset-load")).to_be_disabled()
    expect(page.locator("#f-name")).to_be_editable()
    assert held, "the page asked for its status"
    for route in held:
        route.continue_()
    page.unroute("**/api/status")  # later polls go straight through
    expect(page.locator("#plan-button")).to_be_enabled()
    expect(page.locator("#sequence-plan")).to_be_enabled()
    expect(page.locator("#preset-load")).to_be_enabled()
    expect(page.locator("#service-status")).to_contain_text("4 mock vehicles")
