"""The fleet table follows the vehicle within one telemetry message: the flight's snapshots
and GET /api/vehicles are merged with the newer source winning, so a poll answer asked
before the flight's last snapshot never shows a disarmed vehicle "armed / landing" again,
and a flight's last snapshot (the fleet as it left it) outlives the flight until a newer
poll answers."""

from __future__ import annotations

from playwright.sync_api import Page

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
