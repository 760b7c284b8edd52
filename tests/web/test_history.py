"""Flight history: each mission lists its flights with status badges; a finished flight's
summary, events and plots reopen; replay shows the recorded positions against the plan,
driven by the time slider."""

from __future__ import annotations

import json
from collections.abc import Callable

import httpx
import numpy as np
from playwright.sync_api import Page, Request, expect

from gcs.phases import FlightPhase
from tests.api.support import QUICK_CROSSING, ServiceProcess
from tests.support.waiting import wait_for
from tests.web.conftest import FLY_OPTIONS, PHONE
from tests.web.support import CROSSING_HORIZON_S, assert_fits


def fly_through_the_api(base: str) -> tuple[str, str]:
    """Plan QUICK_CROSSING and start flying it on the mock fleet, as the page's Fly does in
    these tests (FLY_OPTIONS): (mission id, flight id)."""
    scenario = {**QUICK_CROSSING, "name": "history-flight"}
    mission = httpx.post(f"{base}/api/missions?wait=60", json=scenario, timeout=90).json()
    assert mission["plan_ok"], mission
    flight = httpx.post(f"{base}/api/missions/{mission['id']}/flights", json=FLY_OPTIONS,
                        timeout=30).json()
    return mission["id"], flight["id"]


def flight_of(base: str, flight_id: str) -> dict:
    """GET /api/flights/{flight_id}."""
    return httpx.get(f"{base}/api/flights/{flight_id}", timeout=10).json()


def pause_once_flying(base: str, flight_id: str) -> None:
    """Pause the flight as soon as it flies its plan: a paused flight stays live as long as the
    checks on the pages take, however busy the machine (its whole plan lasts a few seconds)."""
    def flying() -> bool:
        got = flight_of(base, flight_id)
        assert not got["finished_at"], got
        return (got.get("live") or {}).get("phase") == FlightPhase.FLYING

    wait_for(flying, f"flight {flight_id} to run its plan", timeout=120.0)
    paused = httpx.post(f"{base}/api/flights/{flight_id}/pause", timeout=30)
    assert paused.status_code == 200, paused.text


def test_a_flight_reopens_and_replays_against_the_plan(
    page: Page, open_page: Callable[..., Page], service: ServiceProcess
) -> None:
    expect(page.locator("#vehicle-table tr.vehicle")).to_have_count(4)  # nothing planned yet
    # The same flight on a phone, open before it starts: loading a page takes seconds on a
    # busy machine, and the whole flight does not last much longer.
    phone = open_page(PHONE)
    expect(phone.locator("#vehicle-table tr.vehicle")).to_have_count(4)
    mission_id, flight_id = fly_through_the_api(service.base_url)
    pause_once_flying(service.base_url, flight_id)
    # A flight started elsewhere (here: the API) shows up on the open pages, with its mission
    # taken into the empty form, so the plan shown is not stale.
    expect(page.locator("#flight-status")).to_have_attribute("data-status", "paused",
                                                                timeout=30_000)
    expect(page.locator("#flight-banner")).to_contain_text("paused")
    expect(page.locator("#f-name")).to_have_value("history-flight")
    expect(page.locator("#mission-title")).to_contain_text(mission_id)
    expect(page.locator("#stale-banner")).to_be_hidden()
    expect(page.locator("#fly-view g.vehicle-icon")).to_have_count(4, timeout=30_000)
    expect(page.locator("#fly-button")).to_be_disabled()  # one flight at a time
    # On the phone: still one header line, nothing sideways.
    expect(phone.locator("#flight-banner")).to_contain_text("paused", timeout=30_000)
    expect(phone.locator("#fly-view g.vehicle-icon")).to_have_count(4, timeout=30_000)
    header = phone.locator("header").bounding_box()
    assert header and header["height"] <= 48
    assert_fits(phone)
    resumed = httpx.post(f"{service.base_url}/api/flights/{flight_id}/resume", timeout=30)
    assert resumed.status_code == 200, resumed.text
    def finished() -> dict | None:
        got = flight_of(service.base_url, flight_id)
        return got if got["finished_at"] else None

    ended = wait_for(finished, f"flight {flight_id} to finish", timeout=150.0, poll=0.1)
    assert ended["status"] == "completed", ended
    record = httpx.get(f"{service.base_url}/api/flights/{flight_id}/record").json()
    page.reload()
    asked: list[str] = []

    def ask(request: Request) -> None:
        asked.append(request.url)

    page.on("request", ask)

    entry = page.locator(f'#mission-list li[data-id="{mission_id}"]')
    expect(entry).to_contain_text("history-flight")
    expect(entry).to_contain_text("1 flight")
    expect(entry.locator(".status-badge.good")).to_have_text("completed")
    entry.click()
    expect(page.locator("#min-separation-value")).to_be_visible(timeout=30_000)
    expect(page.locator("#stale-banner")).to_be_hidden()  # the form is that mission's
    flight = page.locator(f'#flight-list li[data-id="{flight_id}"]')
    expect(flight.locator(".status-badge.good")).to_have_text("completed")
    # Listed from summaries; the events come with the flight opened.
    assert f"{service.base_url}/api/flights?mission_id={mission_id}&limit=500" in asked
    assert not any(url.endswith(f"/missions/{mission_id}/flights") for url in asked)
    page.remove_listener("request", ask)

    flight.click()
    expect(page.locator("#time-label")).to_contain_text(f"replay of flight {flight_id}")
    expect(page.locator("#flight-summary")).to_contain_text("completed: yes")
    expect(page.locator("#event-log")).to_contain_text("flight_start")
    expect(page.locator("#flight-status")).to_have_attribute("data-status", "completed")
    # The separation plot gains the measured separation of that flight, never below what
    # the recorded summary reports by more than its 5 Hz sampling allows.
    measured = page.evaluate("document.getElementById('separation-plot').data.at(-1)")
    assert measured["name"] == f"measured (flight {flight_id})"
    assert min(measured["y"]) >= record["summary"]["min_separation_measured"] - 0.05

    # The slider drives the replay: the recorded positions at that flight time, drawn in
    # the top-down view (labelled) and the 3-D view.
    expect(page.locator("#fly-view g.vehicle-icon")).to_have_count(4)
    expect(page.locator("#fly-view polyline.trail")).to_have_count(4)
    start = record["flight_start"]
    end = round(CROSSING_HORIZON_S * 10)  # the slider's last sample (10 Hz)

    def replayed_at(k: int) -> None:
        page.locator("#time-slider").fill(str(k))
        expect(page.locator("#time-label")).to_contain_text(
            f"t = {k / 10:.1f} s of {CROSSING_HORIZON_S:.1f} s")
        flown = page.evaluate("""() => { const t = document.getElementById('plot3d').data.at(-1);
                                  return {ids: t.text, x: t.x, y: t.y, z: t.z}; }""")
        for i, vid in enumerate(flown["ids"]):
            rec = next(v for v in record["vehicles"] if v["id"] == vid)
            t = np.asarray(rec["telemetry"]["t"]) - start
            p = np.asarray(rec["telemetry"]["position"])
            expected = [np.interp(k / 10, t, p[:, a]) for a in range(3)]
            shown = [flown["x"][i], flown["y"][i], flown["z"][i]]
            assert np.allclose(shown, expected, atol=1e-6), (vid, k, shown, expected)

    for k in (0, 40, end):
        replayed_at(k)
    # A record written before `flight_start` had that name carries it as `mission_start`:
    # it replays on the same flight time.
    older = {key: value for key, value in record.items() if key != "flight_start"}
    page.route(f"**/api/flights/{flight_id}/record", lambda route: route.fulfill(
        status=200, content_type="application/json",
        body=json.dumps({**older, "mission_start": start})))
    page.locator("#time-slider").fill("0")
    page.locator(f'#flight-list li[data-id="{flight_id}"]').click()
    # Replayed again once the slider is back at the end (where a replay starts).
    expect(page.locator("#time-label")).to_contain_text(
        f"replay of flight {flight_id} · t = {CROSSING_HORIZON_S:.1f} s")
    replayed_at(40)
    # The flight it replays arrived: every goal error (measured after the hold at the goals;
    # at the horizon a vehicle may still trail a stalled station) within its tolerance.
    summary = record["summary"]
    assert summary["goal_error_max"] <= summary["goal_tolerance"], summary
