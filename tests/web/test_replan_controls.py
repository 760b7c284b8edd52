"""The page's replan controls during a flight on the mock fleet: a goal marker dragged on the
fly view (its new goal shown, typed further in its row), sent as one replan; a vehicle
dropped from its fleet-table row with the chosen land/hold; a refusal shown with its field;
the replan's state shown. A Playwright route answers the replan requests and records what
the page sends (the replan flown for real through the page: test_replan_flown.py)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from typing import Any

from playwright.sync_api import Page, Route, expect

from tests.api.support import ServiceProcess
from tests.web.support import CROSSING, client_point, fill_scenario, plan


def answered(sent: list[dict[str, Any]], answers: list[tuple[int, dict[str, Any]]]
             ) -> Callable[[Route], None]:
    """A route for POST .../replan: the body into `sent`, the next of `answers` back."""

    def handle(route: Route) -> None:
        body = route.request.post_data_json
        sent.append(body)
        status, answer = answers.pop(0)
        route.fulfill(status=status, content_type="application/json", body=json.dumps(answer))

    return handle


def replan_object(n: int, body: dict[str, Any]) -> dict[str, Any]:
    return {"id": n, "status": "planning", "requested_at": 1.2, "switch_time": 2.2,
            "lead_s": 1.0, "planning_s": None, "goals": body.get("goals", {}),
            "drop": body.get("drop", []), "drop_action": body.get("drop_action", "land"),
            "reason": "operator"}


def test_drag_a_goal_drop_a_vehicle_and_see_refusals(
    open_page: Callable[..., Page], service: ServiceProcess
) -> None:
    sent: list[dict[str, Any]] = []
    refusal = {"status": 422, "field": "goals.a", "reason": "lies inside obstacle 'tower'",
               "errors": [{"field": "goals.a", "reason": "lies inside obstacle 'tower'"}]}
    answers: list[tuple[int, dict[str, Any]]] = [
        (422, refusal),
        (202, {"replan": replan_object(1, {"goals": {"a": [4.0, 1.5, 1.4]}})}),
        (202, {"replan": replan_object(2, {"drop": ["b"], "drop_action": "hold"})}),
    ]
    page = open_page(before=lambda p: p.route("**/api/flights/*/replan",
                                              answered(sent, answers)))
    fill_scenario(page, "replan-controls", 150, CROSSING)  # 30 s: time to replan in
    plan(page)
    expect(page.locator("#replan-panel")).to_be_hidden()  # nothing flying
    page.click("#fly-button")
    expect(page.locator("#replan-panel")).to_be_visible()
    rows = page.locator("#vehicle-state tbody tr")
    expect(rows).to_have_count(4)
    expect(page.locator('#vehicle-state td[data-key="replan"] button')).to_have_count(4)
    expect(page.locator("#fly-view circle.goal-marker")).to_have_count(4)
    expect(page.locator("#replan-send")).to_be_disabled()  # nothing edited yet

    # Drag a's goal marker to (4.0, 1.5): its new goal is shown on the map and in its row.
    marker = page.locator('#fly-view circle.goal-marker[data-id="a"]')
    box = marker.bounding_box()
    assert box is not None
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    target = client_point(page, 4.0, 1.5)
    page.mouse.move(*target, steps=8)
    page.mouse.up()
    expect(page.locator('#fly-view circle.goal-edited[data-id="a"]')).to_have_count(1)
    x_input = page.locator('#replan-goals input[data-field="goals.a[0]"]')
    y_input = page.locator('#replan-goals input[data-field="goals.a[1]"]')
    expect(x_input).to_be_visible()
    # a pixel of the drag is 6 m / 344 px on the view's 400-unit box: within 5 cm
    assert abs(float(x_input.input_value()) - 4.0) < 0.05
    assert abs(float(y_input.input_value()) - 1.5) < 0.05
    # Its height is typed (the drag keeps the old goal's).
    page.fill('#replan-goals input[data-field="goals.a[2]"]', "1.4")
    page.fill('#replan-goals input[data-field="goals.a[0]"]', "4")
    page.fill('#replan-goals input[data-field="goals.a[1]"]', "1.5")
    expect(page.locator("#replan-send")).to_be_enabled()

    # Refused: the reason with its field, the edited goal kept to fix.
    page.click("#replan-send")
    expect(page.locator("#replan-error")).to_have_text(
        "replan refused (422): goals.a: lies inside obstacle 'tower'")
    expect(page.locator("#replan-goals tbody tr")).to_have_count(1)
    # Accepted: the edit is sent as one replan, then cleared; its state shown.
    page.click("#replan-send")
    expect(page.locator("#replan-status")).to_have_text(
        "replan 1: planning · switch at t = 2.2 s · a new goal")
    expect(page.locator("#replan-goals")).to_be_hidden()
    expect(page.locator("#fly-view circle.goal-edited")).to_have_count(0)
    assert sent[0] == sent[1] == {"goals": {"a": [4.0, 1.5, 1.4]}}

    # Drop b, to hold, from its row.
    page.select_option("#drop-action", "hold")
    page.locator('#vehicle-state tr[data-id="b"] td[data-key="replan"] button').click()
    expect(page.locator("#replan-status")).to_have_text(
        "replan 2: planning · switch at t = 2.2 s · b holds")
    assert sent[2] == {"drop": ["b"], "drop_action": "hold"}

    # The flight ends (aborted, or completed already on a busy machine): the controls go.
    page.click("#abort-button")
    expect(page.locator("#flight-status")).to_have_attribute(
        "data-status", re.compile("^(aborted|completed)$"), timeout=120_000)
    expect(page.locator("#replan-panel")).to_be_hidden()
    expect(page.locator("#fly-view circle.goal-marker")).to_have_count(0)
    expect(page.locator('#vehicle-state td[data-key="replan"]')).to_have_count(0)
    assert len(sent) == 3
