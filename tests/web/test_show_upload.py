"""A show tool's file chosen in the page: a Skybrush `.skyc` or a ZIP of its per-drone CSVs is
read by the service (POST /api/imports) into the formation sequence `fleetplan import`
writes, which fills the box ready to plan; a bad file's errors name the file and the row."""

from __future__ import annotations

import base64
import io
import json
import zipfile
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from planner import Plan
from planner.methods.sequence import plan_sequence
from tests.support.shows import csv_zip, ground_show, skyc_import


@pytest.fixture(scope="module")
def show() -> Plan:
    """The 9-drone ground show, its first formation orange, planned."""
    body = ground_show(landing={})
    body["formations"][0]["color"] = "#ff8800"
    result = plan_sequence(body)
    assert result.ok, result.message
    return result.to_plan()


def _box(page: Page) -> dict:
    expect(page.locator("#sequence-kind")).to_contain_text("a sequence, 9 vehicles")
    return json.loads(page.input_value("#sequence-json"))


def test_a_chosen_skyc_fills_the_box_with_its_sequence(
        page: Page, show: Plan, tmp_path: Path) -> None:
    skyc = tmp_path / "show.skyc"
    expected = skyc_import(show, skyc)
    page.click("#sequence-panel summary")
    page.set_input_files("#sequence-file", str(skyc))
    sequence = _box(page)
    assert sequence["formations"] == expected["formations"]
    assert sequence["formations"][0]["color"] == "#ff8800"
    assert "takeoff" in sequence and "landing" in sequence
    expect(page.locator("#sequence-error")).to_have_text("")


def test_a_dropped_csv_zip_fills_the_box_and_a_bad_one_is_named(
        page: Page, show: Plan, tmp_path: Path) -> None:
    page.click("#sequence-panel summary")
    drop = """([name, data]) => {
        const bytes = Uint8Array.from(atob(data), (c) => c.charCodeAt(0));
        const files = new DataTransfer();
        files.items.add(new File([bytes], name, {type: "application/zip"}));
        const panel = document.querySelector("#sequence-panel");
        panel.dispatchEvent(new DragEvent("drop", {dataTransfer: files, bubbles: true,
                                                   cancelable: true}));
    }"""

    zipped = csv_zip(show, tmp_path / "show.zip").read_bytes()
    page.evaluate(drop, ["design.zip", base64.b64encode(zipped).decode()])
    sequence = _box(page)
    assert len(sequence["vehicles"]) == len(show.vehicles)
    assert len(sequence["formations"]) >= 2

    header = b"Time [msec],x [m],y [m],z [m],Red,Green,Blue\n"
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("a.csv", header + b"0,0,0,0,255,0,0\n1000,nan,0,1,255,0,0\n")
    page.evaluate(drop, ["bad.zip", base64.b64encode(buffer.getvalue()).decode()])
    errors = page.locator("#sequence-error")
    expect(errors).to_contain_text("bad.zip was not imported (422)")
    expect(errors).to_contain_text("x [m]: bad.zip:a.csv, line 3: 'nan' is not a finite number")
    assert json.loads(page.input_value("#sequence-json")) == sequence  # the box is kept
    expect(page.locator("#sequence-kind")).to_contain_text("a sequence, 9 vehicles")
