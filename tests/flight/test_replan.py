"""Replanning in flight (`gcs.flight.replan.replan`) on the ideal mock: new goals and a dropped
vehicle switched in at a stream tick, a replan too late to fly, the refusals, and policy
``replan`` around a vehicle whose link is cut."""

from __future__ import annotations

import asyncio
import itertools
import math
import time
from typing import Any

import numpy as np
import pytest

from gcs.errors import StateConflict
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.replan import replan as replan_module
from gcs.flight.run.executor import FlightExecutor
from gcs.phases import EventKind, ReplanStatus, VehiclePhase
from gcs.sim import MockFleet, homes_under
from planner.errors import FieldError
from tests.flight.support import FAST_MOCK, QUICK, mock_ports, short_line, smooth_plan
from tests.support.waiting import every, reached, until

pytestmark = pytest.mark.timeout(150)

#: Eight vehicles 1.5 m apart (R = 1 m) flying 2 m along y at 1 m in 8 s.
EIGHT = short_line(8, steps=40, spacing=1.5)
#: The landing descent of the mock (`FAST_MOCK`), which the predicted motions use too.
OPTIONS = QUICK.replace(land_speed=FAST_MOCK["land_speed"])


async def _sample_truth(mock: MockFleet, out: list[tuple[float, np.ndarray]]) -> None:
    """Every vehicle's true position every 10 ms, all read at one instant in the mock's own
    loop (GCS-stamped telemetry of different vehicles can be skewed on a busy machine)."""
    await every(0.01, lambda: out.append((
        time.monotonic(), np.array([v.true_position_world for v in mock.vehicles]))))


def _closest(samples: list[tuple[float, np.ndarray]], scale: np.ndarray) -> float:
    """Smallest true pair distance over the samples (the plan's metric)."""
    i, j = np.triu_indices(len(samples[0][1]), k=1)
    return min(float(np.min(np.linalg.norm((p[i] - p[j]) / scale, axis=1)))
               for _, p in samples)


async def _fly(plan: Any, options: FlightOptions, during: Any) -> tuple[Any, ...]:
    """Fly `plan` on mock vehicles under its starts, running `during(flight, mock)`;
    returns (flight, record or exception, mock, what `during` returned)."""
    homes = homes_under(plan.scenario.starts)
    async with MockFleet(homes=homes, settle_time=0.5, **mock_ports(len(homes)),
                         **FAST_MOCK) as mock:
        fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
        flight = FlightExecutor(plan, fleet, options)
        task = flight.start()
        found = await during(flight, mock)
        try:
            outcome = await task
        except Exception as exc:
            outcome = exc
        return flight, outcome, mock, found


def _setpoint_steps_ok(record: dict[str, Any], speed: float) -> None:
    """No setpoint jumps: consecutive setpoints are at most `speed` x their tick gap apart."""
    rate = record["options"]["rate_hz"]
    for v in record["vehicles"]:
        sp = v["setpoints"]
        for (t0, p0), (t1, p1) in itertools.pairwise(zip(sp["tick"], sp["position_ned"],
                                                         strict=True)):
            step = float(np.linalg.norm(np.subtract(p1, p0)))
            assert step <= speed * (t1 - t0) / rate + 1e-6, (v["id"], t0, t1, step)


@pytest.mark.flight
def test_eight_vehicles_two_new_goals_and_one_dropped_mid_flight() -> None:
    """Mid-flight two goals change and uav5 is dropped with land: the replan switches at its
    tick, the fleet completes at the new goals, uav5 is streamed down and lands, the true
    separation stays >= R - 0.05 m across the switch and after, and no setpoint jumps."""
    plan = smooth_plan(EIGHT)
    new_goals = {"uav4": [7.0, 3.2, 1.0], "uav6": [8.5, 0.6, 2.0]}

    async def during(flight: FlightExecutor, mock: MockFleet) -> Any:
        await reached(flight, 2.0)
        truth: list[tuple[float, np.ndarray]] = []
        sampler = asyncio.create_task(_sample_truth(mock, truth))
        obj = await flight.replan(new_goals, ["uav5"], "land", "test")
        assert obj["status"] == ReplanStatus.PLANNING and obj["drop"] == ["uav5"]
        # the last tick within the lead after the request (at flight time 2 s or later)
        assert obj["switch_time"] >= 2.0 + OPTIONS.replan_lead_s - 1.0 / OPTIONS.rate_hz - 1e-6
        with pytest.raises(StateConflict):  # one at a time: refused, not queued
            await flight.replan({"uav1": [1.0, 3.0, 2.0]})
        await until(lambda: flight.replans[-1]["status"] != ReplanStatus.PLANNING,
                    "the replan's planning to end", timeout=90.0, poll=0.02)
        snapshot = flight.snapshot()
        assert snapshot["replan"]["status"] == ReplanStatus.SWITCHED, snapshot["replan"]
        assert snapshot["horizon"] == pytest.approx(
            snapshot["replan"]["switch_time"] + snapshot["replan"]["horizon"], abs=1e-3)
        await asyncio.wait([flight.start()])  # its run (start is idempotent) has ended
        sampler.cancel()
        return truth

    flight, record, mock, truth = asyncio.run(_fly(plan, OPTIONS, during))
    assert isinstance(record, dict), record
    summary = record["summary"]
    assert summary["completed"] is True, summary["why"]
    [replanned] = record["replans"]
    assert replanned["status"] == ReplanStatus.SWITCHED, replanned["why"]
    assert 0.0 < replanned["request_to_switch_s"] <= OPTIONS.replan_lead_s + 1e-3
    verification = replanned["plan"]["verification"]
    assert verification["separated"] and verification["within_bounds"]
    # the others kept R from uav5's streamed descent, checked on the plan (uav5 fixed)
    assert verification["closest_fixed"]["id"] == "uav5"
    assert verification["fixed_distance_min"] >= plan.scenario.min_separation - 1e-3
    assert replanned["separation_across_switch"]["min"] is not None
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index(EventKind.REPLAN_STARTED) < kinds.index(EventKind.REPLAN_SWITCHED)
    assert EventKind.REPLAN_MISSED not in kinds
    # at the new goals (where each stood before landing straight down), the others at theirs
    goals = {vid: g for vid, g in zip(plan.scenario.ids, plan.scenario.goals, strict=True)}
    goals |= {vid: np.array(g) for vid, g in new_goals.items()}
    for vid, vehicle in zip(plan.scenario.ids, mock.vehicles, strict=True):
        assert not vehicle.armed
        assert vehicle.position_world[2] == pytest.approx(0.0, abs=0.05)
        if vid != "uav5":
            np.testing.assert_allclose(vehicle.position_world[:2], goals[vid][:2], atol=0.2)
    # the dropped one landed and disarmed short of its old goal, and is named
    assert mock.vehicles[4].position_world[1] < plan.scenario.goals[4][1] - 0.2
    assert summary["dropped"]["uav5"]["action"] == "land"
    assert summary["dropped"]["uav5"]["phase"] == VehiclePhase.LANDED
    assert math.isnan(flight.vehicles[4].goal_error)  # not judged against a goal
    # the true separation from the request to the end of the flight
    r = plan.scenario.min_separation
    assert len(truth) > 200
    assert _closest(truth, np.asarray(plan.scenario.separation_scale)) >= r - 0.05
    _setpoint_steps_ok(record, 1.05 * float(np.max(plan.scenario.limits.velocity_max)))


def _slow_planner(monkeypatch: pytest.MonkeyPatch, delay: float) -> None:
    """Planning that takes `delay` s longer (a loaded planner), deterministic."""
    real = replan_module.plan_replan

    def slow(*args: Any, **kwargs: Any) -> Any:
        time.sleep(delay)
        return real(*args, **kwargs)

    monkeypatch.setattr(replan_module, "plan_replan", slow)


@pytest.mark.flight
def test_a_replan_not_ready_by_its_switch_tick_is_missed_and_the_flight_goes_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A plan later than its switch tick is not flown: status missed, the event says why,
    the fleet completes at its old goals; its planning time sets the next lead."""
    _slow_planner(monkeypatch, 1.0)
    plan = smooth_plan(short_line(2, steps=25))
    options = OPTIONS.replace(replan_lead_s=0.1)

    async def during(flight: FlightExecutor, mock: MockFleet) -> Any:
        await reached(flight, 1.0)
        obj = await flight.replan({"uav1": [1.0, 2.0, 2.0]}, reason="late")
        assert obj["lead_s"] == pytest.approx(0.1)
        await until(lambda: flight.replans[-1]["status"] != ReplanStatus.PLANNING,
                    "the replan's planning to end", timeout=90.0, poll=0.02)
        await until(lambda: flight.replans[-1]["planning_s"] is not None,  # the late plan
                    "the late plan to finish", timeout=90.0, poll=0.02)  # still finishes
        return flight.replan_lead

    _flight, record, mock, lead = asyncio.run(_fly(plan, options, during))
    assert isinstance(record, dict), record
    [missed] = record["replans"]
    assert missed["status"] == ReplanStatus.MISSED and missed["plan"] is None
    assert "lead" in missed["why"] or "switch tick" in missed["why"]
    assert [e for e in record["events"] if e["kind"] == EventKind.REPLAN_MISSED]
    assert lead >= 1.5 * 1.0  # the next lead covers what that one took
    assert record["summary"]["completed"] is True
    for vehicle, goal in zip(mock.vehicles, plan.scenario.goals, strict=True):
        np.testing.assert_allclose(vehicle.position_world[:2], goal[:2], atol=0.2)


@pytest.mark.flight
def test_replan_refusals(monkeypatch: pytest.MonkeyPatch) -> None:
    """Not flying, paused, a second replan while one runs: StateConflict. An unknown vehicle,
    a bad drop action, a goal outside the workspace or too close to another: the field."""
    plan = smooth_plan(short_line(2, steps=25))
    _slow_planner(monkeypatch, 0.5)
    options = OPTIONS.replace(replan_lead_s=2.0)
    before = FlightExecutor(plan, FleetSpec.from_dict(
        {"vehicles": [{"id": vid, "connection": "udpin:127.0.0.1:1", "system_id": n + 1,
                       "home": [0.0, 0.0, 0.0]} for n, vid in enumerate(plan.scenario.ids)]}),
        OPTIONS)
    with pytest.raises(StateConflict):
        asyncio.run(before.replan({"uav1": [1.0, 2.0, 1.0]}))

    async def during(flight: FlightExecutor, mock: MockFleet) -> Any:
        await reached(flight, 0.5)
        fields = []
        for goals, drop, action in [
            ({"nope": [1.0, 2.0, 1.0]}, (), "land"),
            ({}, ["uav9"], "land"),
            ({}, ["uav2"], "jump"),
            ({"uav1": [1.0, 2.0, 99.0]}, (), "land"),
            ({"uav1": [4.0, 3.0, 1.0]}, (), "land"),  # on uav2's goal
            ({"uav2": [1.0, 2.0, 1.0]}, ["uav2"], "land"),
            ({}, ["uav1", "uav2"], "hold"),
        ]:
            with pytest.raises(FieldError) as caught:
                await flight.replan(goals, drop, action)
            fields.append(caught.value.field)
        flight.pause()
        with pytest.raises(StateConflict):
            await flight.replan({"uav1": [1.0, 2.0, 2.0]})
        flight.resume()
        obj = await flight.replan({"uav1": [1.0, 2.0, 2.0]})
        with pytest.raises(StateConflict):
            await flight.replan({"uav2": [4.0, 2.0, 2.0]})
        # paused and resumed after the switch, the fleet holds and goes on on the new plan
        await reached(flight, obj["switch_time"] + 0.3)
        assert flight.replans[-1]["status"] == ReplanStatus.SWITCHED
        flight.pause()
        await asyncio.sleep(0.3)
        flight.resume()
        return fields

    _flight, record, mock, fields = asyncio.run(_fly(plan, options, during))
    assert fields == ["goals.nope", "drop[0]", "drop_action", "goals.uav1", "goals.uav1",
                      "goals.uav2", "drop"]
    assert isinstance(record, dict), record
    assert [r["status"] for r in record["replans"]] == [ReplanStatus.SWITCHED]
    assert record["summary"]["completed"] is True, record["summary"]["why"]
    # judged against (and flown to) its last goal, not the first plan's [1, 3, 1]
    np.testing.assert_allclose(mock.vehicles[0].position_world[:2], [1.0, 2.0], atol=0.2)
    _setpoint_steps_ok(record, 1.05 * float(np.max(plan.scenario.limits.velocity_max)))


@pytest.mark.flight
def test_policy_replan_flies_the_others_around_a_vehicle_whose_link_is_cut() -> None:
    """Eight vehicles, policy replan: uav4's link is cut mid-flight; it lands on its own
    (predicted motion), the other seven replan around it and complete; the flight counts as
    completed with uav4 named; the true separation stays >= R - 0.05 m."""
    plan = smooth_plan(EIGHT)
    options = OPTIONS.replace(policy="replan")

    async def during(flight: FlightExecutor, mock: MockFleet) -> Any:
        await reached(flight, 2.0)
        truth: list[tuple[float, np.ndarray]] = []
        sampler = asyncio.create_task(_sample_truth(mock, truth))
        mock.vehicles[3].faults.silent = True
        await asyncio.wait([flight.start()])  # its run (start is idempotent) has ended
        sampler.cancel()
        return truth

    _flight, record, mock, truth = asyncio.run(_fly(plan, options, during))
    assert isinstance(record, dict), record
    summary = record["summary"]
    assert summary["faults"] == {"uav4": "link_lost"}
    [replanned] = record["replans"]
    assert replanned["status"] == ReplanStatus.SWITCHED, replanned["why"]
    assert replanned["faulty"] == ["uav4"] and "uav4" in replanned["fixed"]
    assert summary["completed"] is True, summary["why"]
    assert any(w.startswith("uav4: fault link_lost, landed on its own") for w in summary["why"])
    for n, (vehicle, goal) in enumerate(zip(mock.vehicles, plan.scenario.goals, strict=True)):
        assert not vehicle.armed
        if n != 3:
            np.testing.assert_allclose(vehicle.position_world[:2], goal[:2], atol=0.2)
    r = plan.scenario.min_separation
    assert _closest(truth, np.asarray(plan.scenario.separation_scale)) >= r - 0.05


@pytest.mark.flight
def test_policy_replan_that_misses_falls_back_to_land_faulty(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """No replan in time around the faulty vehicle: it lands as under land_faulty, the
    events say so, the others fly on their plan (its descent checked clear of them), and
    the flight does not count as completed."""
    _slow_planner(monkeypatch, 1.0)
    plan = smooth_plan(short_line(3, steps=40))
    options = OPTIONS.replace(policy="replan", replan_lead_s=0.1)

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await reached(flight, 1.0)
        mock.vehicles[1].faults.silent = True

    _flight, record, mock, _ = asyncio.run(_fly(plan, options, during))
    assert isinstance(record, dict), record
    [missed] = record["replans"]
    assert missed["status"] == ReplanStatus.MISSED and missed["faulty"] == ["uav2"]
    told = [(e["vehicle"], e["kind"]) for e in record["events"]]
    assert ("uav2", EventKind.REPLAN_MISSED) in told
    assert ("uav2", EventKind.DESCENT_CLEAR) in told  # land_faulty's check, then fly on
    summary = record["summary"]
    assert summary["completed"] is False and "uav2: fault link_lost" in summary["why"]
    assert summary["dropped"] == {}
    for n in (0, 2):
        np.testing.assert_allclose(mock.vehicles[n].position_world[:2],
                                   plan.scenario.goals[n][:2], atol=0.2)
        assert not mock.vehicles[n].armed


#: uav2 hovers 1.5 m above uav1's path and 0.6 m beside it; uav1 passes under it halfway.
#: When uav2 goes down, its descent (and where it lands) is in uav1's way.
UNDER = {
    "name": "under", "dt": 0.2, "steps": 50, "min_separation": 1.0,
    "limits": {"position_min": [0.0, 0.0, 0.0], "position_max": [10.0, 6.0, 4.0],
               "velocity_max": [3.0, 3.0, 3.0], "acceleration_max": [4.0, 4.0, 4.0]},
    "vehicles": [{"id": "uav1", "start": [1.0, 3.0, 1.0], "goal": [9.0, 3.0, 1.0]},
                 {"id": "uav2", "start": [5.0, 3.6, 2.5], "goal": [5.5, 3.6, 2.5]},
                 {"id": "uav3", "start": [1.0, 1.0, 1.0], "goal": [9.0, 1.0, 1.0]}],
}


@pytest.mark.flight
@pytest.mark.parametrize("policy", ["replan", "land_faulty"])
def test_a_faulty_vehicle_landing_in_the_others_way(policy: str) -> None:
    """uav2's link is cut above uav1's path. land_faulty finds its descent across uav1's plan
    and stops the fleet in Hold (aborted, uav1 short of its goal); replan flies uav1 around
    the predicted descent to its goal (completed), keeping R from uav2 in truth."""
    plan = smooth_plan(UNDER)

    async def during(flight: FlightExecutor, mock: MockFleet) -> Any:
        await reached(flight, 1.0)
        truth: list[tuple[float, np.ndarray]] = []
        sampler = asyncio.create_task(_sample_truth(mock, truth))
        mock.vehicles[1].faults.silent = True
        await asyncio.wait([flight.start()])  # its run (start is idempotent) has ended
        sampler.cancel()
        return truth

    flight, outcome, mock, truth = asyncio.run(_fly(plan, OPTIONS.replace(policy=policy),
                                                    during))
    record = flight.record
    assert record is not None
    told = [(e["vehicle"], e["kind"]) for e in record["events"]]
    faulty = np.array([p[1] for _, p in truth])
    others = np.array([p[[0, 2]] for _, p in truth])
    closest = float(np.min(np.linalg.norm(others - faulty[:, None, :], axis=2)))
    r = plan.scenario.min_separation
    assert closest >= r - 0.05
    if policy == "land_faulty":
        assert ("uav2", EventKind.DESCENT_CONFLICT) in told
        assert not isinstance(outcome, dict) and record["summary"]["completed"] is False
        assert mock.vehicles[0].position_world[0] < 5.0  # held short of uav2
        return
    assert isinstance(outcome, dict), outcome
    assert outcome["summary"]["completed"] is True, outcome["summary"]["why"]
    [replanned] = outcome["replans"]
    assert replanned["status"] == ReplanStatus.SWITCHED and replanned["fixed"] == ["uav2"]
    for n in (0, 2):
        np.testing.assert_allclose(mock.vehicles[n].position_world[:2],
                                   plan.scenario.goals[n][:2], atol=0.2)
    # uav2 came down where it was (its prediction), out of the way of the detour
    assert mock.vehicles[1].position_world[2] == pytest.approx(0.0, abs=0.05)
    assert closest >= r  # the others kept R + the prediction's margin, in truth at least R


@pytest.mark.flight
def test_a_replan_through_the_flight_handle_from_another_loop() -> None:
    """`FlightHandle.replan` (how the CLI and the vehicle process reach a flight on its
    vehicle loop): the replan object comes back, refusals cross as raised, and the posted
    snapshot shows the replan."""
    from gcs.flight.host.flight_handle import FlightHandle
    from gcs.flight.host.vehicle_loop import VehicleLoop

    plan = smooth_plan(short_line(2, steps=25))

    async def main() -> tuple[dict[str, Any], Any, dict[str, Any]]:
        vehicles = VehicleLoop(name="fleetplan-test-replan")
        vehicles.start()
        mock = MockFleet(homes=homes_under(plan.scenario.starts), settle_time=0.5,
                         **mock_ports(2), **FAST_MOCK)
        try:
            await vehicles.call(mock.start)
            fleet = FleetSpec.from_dict(mock.fleet_dict(plan.scenario.ids))
            handle = await FlightHandle.create(vehicles, plan, fleet, OPTIONS)
            task = handle.start()
            await until(lambda: (handle.snapshot()["flight_time"] or -1.0) >= 0.5,
                        "flight time 0.5 s", timeout=90.0)
            with pytest.raises(FieldError) as refused:
                await handle.replan({"uav7": [1.0, 2.0, 1.0]})
            obj = await handle.replan({"uav1": [1.0, 2.0, 2.0]}, reason="handle")
            shown = handle.snapshot()["replan"]
            record = await task
            return obj, refused.value.field, {"shown": shown, "record": record}
        finally:
            await vehicles.call(mock.stop)
            await asyncio.to_thread(vehicles.stop)

    obj, field, out = asyncio.run(main())
    assert field == "goals.uav7"
    assert obj["status"] == ReplanStatus.PLANNING and obj["reason"] == "handle"
    assert out["shown"]["id"] == obj["id"]
    assert [r["status"] for r in out["record"]["replans"]] == [ReplanStatus.SWITCHED]
    assert out["record"]["summary"]["completed"] is True


@pytest.mark.flight
def test_a_replan_while_holding_at_the_goals_moves_the_end_and_a_hold_drop_lands_at_the_end(
) -> None:
    """Asked while the fleet holds at its goals: the flight goes on to the new plan's end
    (a second horizon), uav1 to its new goal; uav2, dropped with hold, holds where it stood
    and lands with the others at the end, named as dropped, not judged."""
    plan = smooth_plan(short_line(3, steps=15))  # 3 s
    options = OPTIONS.replace(hold_at_goal=3.0)

    async def during(flight: FlightExecutor, mock: MockFleet) -> Any:
        await reached(flight, plan.scenario.horizon + 0.5)
        obj = await flight.replan({"uav1": [1.0, 1.5, 1.5]}, ["uav2"], "hold")
        return obj

    _flight, record, mock, obj = asyncio.run(_fly(plan, options, during))
    assert isinstance(record, dict), record
    assert [r["status"] for r in record["replans"]] == [ReplanStatus.SWITCHED]
    assert record["horizon"] == pytest.approx(obj["switch_time"] + record["replans"][0]["horizon"],
                                              abs=1e-3)
    assert [e["kind"] for e in record["events"]].count(EventKind.HORIZON) == 2
    summary = record["summary"]
    assert summary["completed"] is True, summary["why"]
    assert summary["dropped"] == {"uav2": {"action": "hold", "reason": "operator",
                                           "phase": VehiclePhase.LANDED}}
    np.testing.assert_allclose(mock.vehicles[0].position_world[:2], [1.0, 1.5], atol=0.2)
    np.testing.assert_allclose(mock.vehicles[1].position_world[:2],
                               plan.scenario.goals[1][:2], atol=0.2)
    assert not any(v.armed for v in mock.vehicles)
