"""The fleet table follows the vehicle within one telemetry message: the flight's snapshots
and GET /api/vehicles are merged with the newer source winning, so a poll answer asked
before the flight's last snapshot never shows a disarmed vehicle "armed / landing" again,
and a flight's last snapshot (the fleet as it left it) outlives the flight until a newer
poll answers."""

from __future__ import annotations

import json
import re
from collections.abc import Callable

import httpx
from playwright.sync_api import Page, Route, expect

from tests.web.support import CROSSING, CROSSING_STEPS, fill_scenario, plan

# Run in one task, so that no poll of the page's own lands between the state set and the
# table read: the `armed` and `phase` cells of vehicle a for each case.
_CASES = """async () => {
    const { fleet, flight } = await import("/state.js");
    const { showVehicleTable } = await import("/fleettable.js");
    const saved = {vehicles: fleet.vehicles, vehiclesAt: fleet.vehiclesAt, live: flight.live,
                   liveAt: flight.liveAt, active: flight.active};
    const polled = [{id: "a", link: "flight", heartbeat_age: 0.1, mode: "OFFBOARD",
                     armed: true, position: [0, 0, 0.2]}];
    const snapshot = (armed, phase) => ({phase: "landing", flight_time: 9,
        min_separation_live: 1, vehicles: [{id: "a", phase, armed, mode: "AUTO.LAND",
                                            heartbeat_age: 0.1, position: [0, 0, 0]}]});
    const now = performance.now() + 1e9;  // later than any poll of the page's own
    const row = '#vehicle-state tr[data-id="a"]';
    const cell = (key) => document.querySelector(`${row} td[data-key="${key}"]`).textContent;
    // the snapshot (disarmed, in `phase`) and the poll, each `age` ms before now
    const show = (phase, liveAge, pollAge, active) => {
        Object.assign(fleet, {vehicles: polled, vehiclesAt: now - pollAge});
        Object.assign(flight, {live: snapshot(false, phase), liveAt: now - liveAge, active});
        showVehicleTable();
        return [cell("armed"), cell("phase")];
    };
    const out = {
        // flying: the snapshot after the disarm is newer than the last poll
        disarmed: show("landed", 0, 1500, true),
        // flying: a poll newer than the snapshot gives mode and armed, the snapshot the phase
        polledLater: show("landing", 1500, 0, true),
        // the flight has ended: its last snapshot stays over an older poll
        ended: show("landed", 0, 1500, false),
        // ... until a newer poll answers: the fleet between flights
        afterPoll: show("landed", 1500, 0, false),
    };
    Object.assign(fleet, {vehicles: saved.vehicles, vehiclesAt: saved.vehiclesAt});
    Object.assign(flight, {live: saved.live, liveAt: saved.liveAt, active: saved.active});
    showVehicleTable();
    return out;
}"""


def test_the_newer_of_telemetry_and_poll_wins_in_the_fleet_table(page: Page) -> None:
    page.wait_for_selector("#vehicle-state tbody tr[data-id]")
    assert page.evaluate(_CASES) == {
        "disarmed": ["no", "landed"],
        "polledLater": ["armed", "landing"],
        "ended": ["no", "landed"],
        "afterPoll": ["armed", "idle"],
    }


def test_after_a_flight_the_table_shows_the_fleet_landed_not_an_older_poll(
        open_page: Callable[..., Page]) -> None:
    """A real flight on the mocks whose last fleet poll answered mid-flight (every vehicle
    armed) and no later poll answers: as the flight ends the table shows every vehicle
    disarmed and landed, from the stream's last telemetry."""
    state: dict[str, bool] = {"flying": False, "answered": False}
    held: list[Route] = []

    def vehicles(route: Route) -> None:
        if state["answered"]:
            held.append(route)  # unanswered: no poll newer than the flight's last snapshot
            return
        answer = httpx.get(route.request.url, timeout=30).json()
        if state["flying"]:
            for v in answer["vehicles"]:
                v.update(armed=True, mode="OFFBOARD")
            state["answered"] = True
        route.fulfill(status=200, content_type="application/json", body=json.dumps(answer))

    page = open_page(before=lambda p: p.route(re.compile(r".*/api/vehicles$"), vehicles))
    fill_scenario(page, "browser-table", CROSSING_STEPS, CROSSING)
    plan(page)
    page.click("#fly-button")
    status = page.locator("#flight-status")
    expect(status).to_have_attribute("data-status", "running", timeout=30_000)
    state["flying"] = True
    expect(status).to_have_attribute("data-status", "completed", timeout=90_000)
    assert state["answered"]  # the flight outlasted a poll: the table had a mid-flight one
    cells = page.evaluate("""() => Array.from(document.querySelectorAll(
        "#vehicle-state tbody tr[data-id]"), (tr) => [
        tr.querySelector('td[data-key="armed"]').textContent,
        tr.querySelector('td[data-key="phase"]').textContent])""")
    assert cells == [["no", "landed"]] * len(CROSSING)
    for route in held:
        route.abort()
