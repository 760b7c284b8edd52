"""Bring your own fleet to the page: a plain scenario pasted, a plan made by the CLI chosen as
a file (verified again by the service, then flown on the mock fleet), a file dropped on the
panel; a tampered plan refused naming why; the server's limits said before they are met, and
a generator count over them refused with the fix instead of cut down."""

from __future__ import annotations

import json
from pathlib import Path

from playwright.sync_api import Page, expect

from gcs.cli.main import main
from tests.api.support import QUICK_CROSSING, QUICK_PAIR, ServiceProcess


def _cli_plan(tmp_path: Path, scenario: dict) -> Path:
    """A plan file written by `fleetplan plan`, as a user brings one."""
    source, plan = tmp_path / "scenario.json", tmp_path / f"{scenario['name']}.plan.json"
    source.write_text(json.dumps(scenario))
    assert main(["plan", str(source), "-o", str(plan), "-q"]) == 0
    return plan


def test_a_pasted_scenario_is_planned_as_it_is(page: Page) -> None:
    page.click("#sequence-panel summary")
    page.fill("#sequence-json", json.dumps(QUICK_PAIR))
    expect(page.locator("#sequence-kind")).to_have_text(
        "a scenario, 2 vehicles: planned as it is")
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("converged, verified", timeout=60_000)
    expect(page.locator("#mission-title")).to_contain_text("quick-pair")


def test_a_cli_plan_chosen_as_a_file_is_verified_again_and_flown(
        page: Page, service: ServiceProcess, tmp_path: Path) -> None:
    plan = _cli_plan(tmp_path, QUICK_CROSSING)
    page.click("#sequence-panel summary")
    page.set_input_files("#sequence-file", str(plan))
    expect(page.locator("#sequence-kind")).to_have_text(
        "a plan, 4 vehicles: verified again by the service and stored, ready to fly")
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("converged, verified", timeout=60_000)
    expect(page.locator("#mission-title")).to_contain_text("quick-crossing")
    expect(page.locator("#fly-button")).to_be_enabled(timeout=30_000)
    page.click("#fly-button")
    status = page.locator("#flight-status")
    expect(status).to_have_attribute("data-status", "running", timeout=30_000)
    expect(status).to_have_attribute("data-status", "completed", timeout=90_000)


def test_a_file_dropped_on_the_panel_fills_the_box(page: Page, tmp_path: Path) -> None:
    page.click("#sequence-panel summary")
    page.evaluate("""(text) => {
        const data = new DataTransfer();
        data.items.add(new File([text], "pair.json", {type: "application/json"}));
        const panel = document.querySelector("#sequence-panel");
        panel.dispatchEvent(new DragEvent("dragover", {dataTransfer: data, bubbles: true,
                                                       cancelable: true}));
        panel.dispatchEvent(new DragEvent("drop", {dataTransfer: data, bubbles: true,
                                                   cancelable: true}));
    }""", json.dumps(QUICK_PAIR))
    expect(page.locator("#sequence-kind")).to_have_text(
        "a scenario, 2 vehicles: planned as it is")
    assert json.loads(page.input_value("#sequence-json")) == QUICK_PAIR


def test_a_tampered_plan_is_refused_naming_why(page: Page, tmp_path: Path) -> None:
    plan = json.loads(_cli_plan(tmp_path, QUICK_PAIR).read_text())
    first = plan["vehicles"][0]["position"]
    plan["vehicles"][1]["position"] = [first[0], *first[:-1]]  # b flies just behind a
    page.click("#sequence-panel summary")
    page.fill("#sequence-json", json.dumps(plan))
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("rejected (422)")
    expect(page.locator("#sequence-error")).to_contain_text("plan: this plan may not be flown")
    page.fill("#sequence-json", json.dumps({"hello": 1}))
    page.click("#sequence-plan")
    expect(page.locator("#sequence-error")).to_contain_text(
        "must be a JSON object: a scenario (with vehicles)")


def test_the_limits_are_said_and_a_count_over_them_is_refused_not_cut(page: Page) -> None:
    limits = page.locator("#server-limits")
    expect(limits).to_contain_text("This server plans up to 128 vehicles, ")
    expect(limits).to_contain_text("max_vehicles")
    rows = page.locator("#vehicle-table tr.vehicle")
    expect(rows).not_to_have_count(0)
    before = rows.count()
    page.select_option("#preset", "gen:random")
    page.fill("#preset-count", "200")
    page.click("#preset-load")
    expect(page.locator("#preset-error")).to_contain_text(
        "200 exceed this server's limit of 128 (setting max_vehicles")
    expect(rows).to_have_count(before)
    page.fill("#preset-count", "12")
    page.click("#preset-load")
    expect(rows).to_have_count(12)
    expect(page.locator("#preset-error")).to_have_text("")
