"""The page's formation sequence input: paste (or load) a sequence, plan it, see the stitched
plan in the same views with its formations and CSV downloads, fly it; errors name fields."""

from __future__ import annotations

import copy
import json

import httpx
from playwright.sync_api import Page, expect

from tests.api.support import GOALS, OUT_AND_BACK, ServiceProcess

#: Out to the crossed formation only (6.8 s): the sequence's flight kept short.
OUT: dict = {**OUT_AND_BACK, "name": "out", "formations": OUT_AND_BACK["formations"][:2]}
#: OUT lit: red at home, fading to blue over the leg (0.4 to 6.4 s).
LIT: dict = {**OUT, "formations": [{**OUT["formations"][0], "color": "#ff0000"},
                                   {**OUT["formations"][1], "color": "#0000ff",
                                    "lights": "fade"}]}
#: The longest gap between two animation frames since `window.__longest` was reset.
FRAMES = """() => { window.__longest = 0; let last = performance.now();
  const tick = (now) => { window.__longest = Math.max(window.__longest, now - last);
                          last = now; requestAnimationFrame(tick); };
  requestAnimationFrame(tick); }"""


def paste(page: Page, body: dict) -> None:
    page.click("#sequence-panel summary")
    page.fill("#sequence-json", json.dumps(body))


def test_paste_plan_show_download_and_fly_a_sequence(page: Page, service: ServiceProcess
                                                    ) -> None:
    paste(page, OUT)
    expect(page.locator("#sequence-plan")).to_be_enabled()
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    expect(page.locator("#sequence-summary")).to_contain_text("sequence: home → crossed ·")
    expect(page.locator("#sequence-summary")).to_contain_text("6.8 s")
    expect(page.locator("#time-label")).to_contain_text("of 6.8 s")
    mission_id = page.locator("#mission-title").inner_text().split("·")[1].strip()
    mission = httpx.get(f"{service.base_url}/api/missions/{mission_id}").json()
    assert mission["plan"]["sequence"]["formations"][1]["name"] == "crossed"

    links = page.locator("#sequence-downloads a")
    expect(links).to_have_count(4)
    href = links.nth(2).get_attribute("href")
    assert href is not None and "vehicle=c" in href
    rows = httpx.get(service.base_url + href).text.strip().splitlines()
    assert rows[0] == "Time [msec],x [m],y [m],z [m]"
    t, *xyz = (float(c) for c in rows[1 + 66].split(","))  # t = 6.6 s at 10 Hz: crossed
    assert t == 6600 and max(abs(a - b) for a, b in zip(xyz, GOALS[2], strict=True)) < 1e-3

    # Editing the sequence makes the plan shown stale: Fly is refused until it is planned.
    expect(page.locator("#fly-button")).to_be_enabled(timeout=30_000)
    page.fill("#sequence-json", json.dumps({**OUT, "name": "edited"}))
    expect(page.locator("#stale-banner")).to_contain_text("sequence has changed")
    expect(page.locator("#fly-button")).to_be_disabled()
    page.fill("#sequence-json", json.dumps(OUT))
    expect(page.locator("#fly-button")).to_be_enabled()

    page.click("#fly-button")
    status = page.locator("#flight-status")
    expect(status).to_have_attribute("data-status", "running", timeout=30_000)
    expect(status).to_have_attribute("data-status", "completed", timeout=90_000)


def test_a_lit_sequence_draws_each_drone_in_its_light_colour_at_the_slider_s_time(
        page: Page) -> None:
    """Red at home, fading to blue over the leg (0.4 to 6.4 s): purple half way, in the fly
    view's planned rings and the 3-D view's planned-now markers."""
    paste(page, LIT)
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    ring = page.locator('#fly-view .planned-icon[data-id="a"]')
    markers = "document.getElementById('plot3d').data.find((t) => t.name === 'planned now')"
    for k, label, colour in [(0, "t = 0.0 s", "#ff0000"), (34, "t = 3.4 s", "#800080"),
                             (68, "t = 6.8 s", "#0000ff")]:
        page.locator("#time-slider").fill(str(k))
        expect(page.locator("#time-label")).to_contain_text(label)
        expect(ring).to_have_attribute("stroke", colour)
        page.wait_for_function(f"{markers}?.marker.color.every((c) => c === '{colour}')")


def test_playing_a_lit_sequence_plays_it_in_colour(page: Page) -> None:
    """▶ plays the plan on the slider with the drones in their light's colour as it goes:
    red, then the fade's purples, then blue, with frames coming all along (the figures for a
    1,000-drone show are bench/playback.py's)."""
    paste(page, LIT)
    page.click("#sequence-plan")
    expect(page.locator("#plan-state")).to_contain_text("converged", timeout=60_000)
    ring = page.locator('#fly-view .planned-icon[data-id="a"]')
    expect(ring).to_have_attribute("stroke", "#ff0000")
    page.evaluate(FRAMES)
    page.click("#play")
    seen = set()
    for _ in range(200):  # about 10 s: the 6.8 s plan played once
        seen.add(ring.get_attribute("stroke"))
        if "#0000ff" in seen:
            break
        page.wait_for_timeout(50)
    page.click("#play")
    assert "#0000ff" in seen and len(seen) >= 3, seen  # red, a purple, blue
    assert page.evaluate("window.__longest") < 2000  # bound: frames kept coming (ms)


def test_sequence_errors_name_the_field(page: Page) -> None:
    bad = copy.deepcopy(OUT_AND_BACK)
    del bad["formations"][2]["duration"]
    paste(page, bad)
    expect(page.locator("#sequence-plan")).to_be_enabled()
    page.click("#sequence-plan")
    expect(page.locator("#sequence-error")).to_contain_text(
        "formations[2].duration: is required")
    expect(page.locator("#plan-state")).to_contain_text("rejected (422)")
    page.fill("#sequence-json", "{not json")
    page.click("#sequence-plan")
    expect(page.locator("#sequence-error")).to_contain_text("not valid JSON")
