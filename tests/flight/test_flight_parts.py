"""The executor's parts on their own: flight clock, fault policy, event fan-out, snapshot."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import pytest

from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.procedure.context import FlightContext
from gcs.flight.run.events import EventFanout
from gcs.flight.run.record import FlightRecorder
from gcs.flight.run.snapshot import flight_snapshot
from gcs.flight.safety.descent import DescentConflict, descent_conflicts
from gcs.flight.safety.policy import FaultPolicy, Responder
from gcs.flight.timeline.clock import FlightClock
from gcs.phases import EventKind, VehiclePhase
from tests.flight.fakes import fake_vehicle
from tests.flight.support import short_line, smooth_plan


def test_flight_clock_stops_while_paused_and_moves_its_start_on() -> None:
    clock = FlightClock(rate=10.0, epoch=100.0, t0=100.0)
    assert clock.flight_time() is None
    clock.begin(20)  # flight time 0 at tick 20 = GCS-clock 2.0 s
    assert clock.start == pytest.approx(2.0)
    pause = clock.stop(50)
    assert pause.plan_tick == 30
    assert clock.flight_time() == pytest.approx(3.0)  # held, whatever the wall clock says
    ended, paused = clock.restart(80)
    assert ended is pause and paused == pytest.approx(3.0)
    assert clock.start_tick == 50 and clock.paused_total == pytest.approx(3.0)
    assert clock.pauses == [[pytest.approx(5.0), pytest.approx(8.0)]]
    assert clock.end_pause() is None  # nothing paused: nothing to end


def test_a_pause_cut_short_by_the_end_of_the_flight_gets_an_end() -> None:
    clock = FlightClock(rate=10.0, epoch=0.0, t0=0.0)
    clock.begin(0)
    clock.stop(10)
    assert clock.end_pause() is not None
    assert clock.pause is None and clock.pauses[-1][1] is not None


def _policy(policy: str, descent: Callable[[Any], list[DescentConflict] | None] = lambda v: [],
            landing: str = "planned"
            ) -> tuple[FaultPolicy, list[Any], list[tuple[str | None, str]]]:
    calls: list[Any] = []
    events: list[tuple[str | None, str]] = []

    class Carried(Responder):
        """Notes what the policy asks for; an abort asked for is under way from then on."""

        async def land(self, v: Any) -> None:
            calls.append(("land", v.id))

        async def abort(self, action: str, reason: str) -> None:
            calls.append(("abort", action, reason))

        def aborting(self) -> bool:
            return any(call[0] == "abort" for call in calls)

        def descent(self, v: Any) -> list[DescentConflict] | None:
            return descent(v)

        def replan(self, v: Any, kind: str) -> None:
            calls.append(("replan", v.id))

    out = FaultPolicy(FlightContext(FlightOptions(policy=policy, landing=landing),
                                    lambda vid, kind, _d: events.append((vid, kind))),
                      lambda: 1.0, Carried())
    return out, calls, events


@pytest.mark.parametrize(("policy", "expected"), [
    ("land_faulty", ("land", "uav1")),
    ("land_all", ("abort", "land", "uav1 link_lost (gone)")),
    ("hold_all", ("abort", "hold", "uav1 link_lost (gone)")),
])
def test_each_policy_does_what_it_says(policy: str, expected: tuple[str, ...]) -> None:
    async def main() -> tuple[Any, list[Any], list[tuple[str | None, str]]]:
        p, calls, events = _policy(policy)
        v = fake_vehicle(0)
        p.on_fault(v, "link_lost", "gone")
        await asyncio.gather(*p.tasks)
        return v, calls, events

    v, calls, events = asyncio.run(main())
    assert calls == [expected]
    # land_faulty cannot steer a vehicle whose link is lost down a landing plan: PX4 lands it
    fallback = [("uav1", EventKind.LANDING_FALLBACK), ("uav1", EventKind.DESCENT_CLEAR)] \
        if policy == "land_faulty" else []
    assert events == [("uav1", EventKind.FAULT), *fallback]
    assert v.fault == "link_lost" and v.phase == VehiclePhase.FAULTY and v.fault_time == 1.0


@pytest.mark.parametrize(("descent", "why"), [
    (lambda v: [DescentConflict("uav2", 0.4, 3.2)], "uav2 0.40 m at t=3.2 s"),
    (lambda v: None, "not checked"),
])
@pytest.mark.parametrize(("landing", "action"), [("planned", "land"), ("px4", "hold")])
def test_land_faulty_stops_the_others_unless_the_descent_is_clear(
        descent: Callable[[Any], list[DescentConflict] | None], why: str, landing: str,
        action: str) -> None:
    """An unsteerable vehicle goes straight down: where that descent would come within R of
    another's plan (or cannot be checked), the others do not fly on: they land by a landing
    plan that keeps clear of it, or (landing px4, no plan) hold where they are."""
    async def main() -> tuple[list[Any], list[str]]:
        said: list[str] = []
        p, calls, _events = _policy("land_faulty", descent, landing)
        p.emit = lambda vid, kind, detail: said.append(f"{kind}: {detail}")
        p.on_fault(fake_vehicle(0), "link_lost", "gone")
        await asyncio.gather(*p.tasks)
        return calls, said

    calls, said = asyncio.run(main())
    assert calls[0] == ("land", "uav1")
    assert calls[1][:2] == ("abort", action) and "across the others' plans" in calls[1][2]
    conflict = [s for s in said if s.startswith(EventKind.DESCENT_CONFLICT)]
    assert len(conflict) == 1 and why in conflict[0]


def test_a_descent_column_is_checked_against_the_others_plan() -> None:
    """uav2 flies y 1 -> 3 at x 4, z 1 (R = 1 m): a descent right above its path crosses it;
    1.5 m beside it, or ending 1.3 m below it, does not; 1.5 m beside is too close for 2 m."""
    plan = smooth_plan(short_line(2))
    assert [c.vehicle for c in descent_conflicts(plan, "uav1", [4.0, 2.0, 3.0], 0.0, 1.0)] \
        == ["uav2"]
    [hit] = descent_conflicts(plan, "uav1", [4.0, 2.0, 3.0], 0.0, 1.0)
    assert hit.distance < 0.05 and 0.0 <= hit.flight_time <= plan.scenario.horizon
    assert descent_conflicts(plan, "uav1", [2.5, 2.0, 3.0], 0.0, 1.0) == []
    assert [c.vehicle for c in descent_conflicts(plan, "uav1", [2.5, 2.0, 3.0], 0.0, 2.0)] \
        == ["uav2"]
    # a column that ends below uav2's altitude (a vehicle already low) is clear of it
    assert descent_conflicts(plan, "uav1", [4.0, 2.0, -0.3], 0.0, 1.0, ground=-1.0) == []
    # the faulty vehicle's own plan never counts
    assert descent_conflicts(plan, "uav2", [4.0, 2.0, 3.0], 0.0, 1.0) == []


def test_land_faulty_lands_the_fleet_by_a_plan_when_the_vehicle_can_be_steered() -> None:
    """A vehicle off its plan (a tracking error) still follows setpoints: rather than send it
    straight down through the others' airspace, land_faulty lands the whole fleet by a
    landing plan (an abort with land); with `landing: px4` it lands alone."""
    async def main(landing: str) -> list[Any]:
        p, calls, _events = _policy("land_faulty")
        p.options = p.options.replace(landing=landing)
        p.on_fault(fake_vehicle(0), "tracking_error", "1.2 m from the plan")
        await asyncio.gather(*p.tasks)
        return calls

    [(what, action, reason)] = asyncio.run(main("planned"))
    assert (what, action) == ("abort", "land") and "landing plan" in reason
    assert asyncio.run(main("px4")) == [("land", "uav1")]


def test_a_separation_alarm_holds_everyone_once() -> None:
    async def main() -> list[Any]:
        p, calls, _events = _policy("land_faulty")
        p.on_separation(0.4, 0.7)
        await asyncio.gather(*p.tasks)
        p.on_separation(0.3, 0.7)  # the abort is under way: no second one
        return calls

    assert asyncio.run(main()) == [("abort", "hold", "separation 0.40 m")]


def test_events_reach_the_record_and_every_subscriber_until_closed() -> None:
    async def main() -> tuple[list[str], list[str], FlightRecorder]:
        recorder = FlightRecorder(["uav1"], [1])
        fanout = EventFanout(recorder, lambda: 0.5)
        seen: list[list[str]] = [[], []]

        async def watch(i: int) -> None:
            async for event in fanout.events():
                seen[i].append(event["kind"])

        watchers = [asyncio.create_task(watch(i)) for i in range(2)]
        await asyncio.sleep(0)
        fanout.emit("uav1", EventKind.ARMED, "after 1 attempt(s)")
        fanout.emit(None, EventKind.HORIZON)
        fanout.close()
        await asyncio.wait_for(asyncio.gather(*watchers), 5.0)  # bound
        late = [e async for e in fanout.events()]  # a subscriber after the end gets nothing
        assert late == []
        return seen[0], seen[1], recorder

    first, second, recorder = asyncio.run(main())
    assert first == second == ["armed", "horizon"]
    assert [e["t"] for e in recorder.events] == [0.5, 0.5]


def test_snapshot_carries_the_flight_time_under_one_name() -> None:
    v = fake_vehicle(0, home=(1.0, 2.0, 0.0))
    snap = flight_snapshot(VehiclePhase.FLYING, 3.5, 6.0, float("inf"), [v], 7)
    assert snap["flight_time"] == 3.5 and "mission_time" not in snap
    assert snap["min_separation_live"] is None  # no pair yet: not a number to show
    [vehicle] = snap["vehicles"]
    # LOCAL_NED (0, 0, -1.5) from a home at (1, 2, 0): 1.5 m up in the world frame
    assert vehicle["position"] == pytest.approx([1.0, 2.0, 1.5])
    assert vehicle["mode"] == "OFFBOARD" and vehicle["heartbeat_age"] is not None


def test_dropped_packets_are_told_as_they_happen_at_most_every_five_seconds() -> None:
    """Someone else talking as a vehicle is told live (once per DROPS_NOTE_S per vehicle,
    with the counts and their rate since the last time, and the latest source), not only in
    the record."""
    from gcs.flight.safety.monitor import DROPS_NOTE_S, FleetMonitor
    from tests.flight.fakes import Findings, fake_link
    from tests.flight.support import line_scenario, smooth_plan

    vehicles = [fake_vehicle(0), fake_vehicle(1)]
    told: list[tuple[str | None, str]] = []

    def emit(vehicle: str | None, kind: str, detail: str = "") -> None:
        assert kind == EventKind.DROPPED_PACKETS
        told.append((vehicle, detail))

    monitor = FleetMonitor(vehicles, smooth_plan(line_scenario(2)),
                           FlightContext(FlightOptions(), emit), Findings())
    link = fake_link(vehicles[1])
    monitor.report_drops(100.0)
    assert told == []  # nothing dropped: nothing said
    link.telemetry.security.foreign_source = 12
    link.dropped_from["foreign_source"] = (("127.0.0.1", 5555), 1)
    monitor.report_drops(100.0)
    assert told == [("uav2", "12 more packets dropped (12 foreign_source), the latest from "
                             "127.0.0.1:5555 (component 1)")]
    link.telemetry.security.foreign_source = 20
    monitor.report_drops(100.0 + DROPS_NOTE_S / 2)  # too soon: kept for the next report
    assert len(told) == 1
    monitor.report_drops(100.0 + DROPS_NOTE_S)
    assert told[-1] == ("uav2", "8 more packets dropped in 5.0 s, 1.6/s (8 foreign_source), "
                                "the latest from 127.0.0.1:5555 (component 1)")
    monitor.report_drops(200.0)  # no new drops
    assert len(told) == 2


def test_replays_alone_are_told_as_the_vehicles_own_repeated_timestamps() -> None:
    """PX4 signs with old timestamps for a few seconds after it boots and now and then
    repeats one (about one packet a vehicle every half minute on SITL): drops that are all
    replays come from the pinned peer's own address and are told as that, and the CLI does
    not blame another process on the vehicle's port; any other drop keeps that warning."""
    from gcs.cli.hints import live_warning
    from gcs.flight.link.signing import REPEATED_TIMESTAMPS
    from gcs.flight.safety.monitor import drops_text

    peer = (("127.0.0.1", 14581), 1)
    replays = drops_text({"replayed": 1, "unsigned": 0}, peer, 24.6)
    assert replays.startswith("1 more packets dropped in 24.6 s, 0.0/s (1 replayed), the "
                              "latest from 127.0.0.1:14581 (component 1): ")
    assert replays.endswith(REPEATED_TIMESTAMPS)
    warning = live_warning({"kind": EventKind.DROPPED_PACKETS, "vehicle": "b",
                            "detail": replays}, "--base-port")
    assert warning is not None and "something else is sending" not in warning
    assert "recorded traffic played back" in warning
    mixed = drops_text({"replayed": 1, "unsigned": 40}, peer, 5.0)
    assert REPEATED_TIMESTAMPS not in mixed
    warning = live_warning({"kind": EventKind.DROPPED_PACKETS, "vehicle": "b",
                            "detail": mixed}, "--base-port")
    assert warning is not None and "something else is sending" in warning
