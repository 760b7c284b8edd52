"""The GCS against the mock's "px4" realism (what PX4 v1.16 SIH SITL does): arming refused
for the first seconds after boot, doubled COMMAND_ACKs, a noisy wandering estimate with its
reported accuracy, and a 4-vehicle crossing flown and judged on all that. Real time, short."""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any

import pytest

from gcs.autopilot import px4
from gcs.errors import FlightAborted
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.flight.procedure import vehicle as gcs_vehicle
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.safety.margin import scenario_for_fleet
from gcs.phases import EventKind
from gcs.sim import MockFleet, homes_under
from gcs.wire import mavlink
from planner import plan as make_plan
from tests.api.support import QUICK_CROSSING
from tests.flight.support import FAST_MOCK, mock_ports, short_line, smooth_plan
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(150)


async def _link(mock: MockFleet, index: int = 0) -> tuple[LinkHub, VehicleLink]:
    hub = LinkHub()
    await hub.__aenter__()
    v = mock.vehicles[index]
    link = await hub.add(f"uav{index + 1}", mock.gcs_url(index), v.system_id)
    return hub, link


def test_arming_is_temporarily_rejected_after_boot_and_the_gcs_retry_arms() -> None:
    """PX4 SITL: first HEARTBEAT ~1.5 s after start, arming TEMPORARILY_REJECTED ("resolve
    system health failures first") until ~3.5 s; the GCS's arm() retries and arms."""

    async def run() -> dict[str, Any]:
        async with MockFleet(1, realism="px4", **mock_ports(1)) as mock:
            hub, link = await _link(mock)
            try:
                assert await link.wait_for(lambda t: t.heartbeat_time is not None, 10.0)
                first_heartbeat = mock.now()
                attempts = await gcs_vehicle.arm(link, timeout=15.0, confirm_timeout=3.0)
                armed_at = mock.now()
                texts = list(link.telemetry.statustexts)
                await gcs_vehicle.disarm(link)
                return {"first": first_heartbeat, "attempts": attempts, "armed": armed_at,
                        "texts": texts, "settle": mock.config.settle_time,
                        "events": list(mock.vehicles[0].events)}
            finally:
                await hub.close()

    out = asyncio.run(run())
    assert out["first"] >= 1.5  # deaf and silent while booting
    assert out["attempts"] >= 2, out  # the first try came before the estimator settled
    assert out["settle"] <= out["armed"] < out["settle"] + 3.0
    assert any(t.startswith("Arming denied: Resolve system health") for t in out["texts"]), out
    assert [what for _, what in out["events"]].count("armed") == 1


def test_doubled_mode_acks_are_counted_once_and_never_answer_a_later_command() -> None:
    """PX4 ACKs DO_SET_MODE twice. A refused mode change's second ACK still on its way when
    the next DO_SET_MODE goes out must not be taken for that command's answer."""

    async def run() -> dict[str, Any]:
        # the second ACK 0.15 s late (inside the GCS's window for it), each packet 0.2 s on
        # its way: the refusal's second ACK arrives before the answer to the next command
        # (0.4 s round trip)
        async with MockFleet(1, realism="px4", duplicate_ack_delay=0.15, boot_time=0.0,
                             **mock_ports(1)) as mock:
            mock.vehicles[0].faults.delay = 0.2
            hub, link = await _link(mock)
            try:
                assert await link.wait_for(lambda t: t.heartbeat_time is not None, 10.0)
                cmd = mavlink.MAV_CMD_DO_SET_MODE
                # no setpoint stream: OFFBOARD is refused (TEMPORARILY_REJECTED, twice)
                refused = await link.command(cmd, px4.OFFBOARD.command_params)
                # at once: Land, which is accepted (once, then its own duplicate)
                accepted = await link.command(cmd, px4.LAND.command_params)
                await asyncio.sleep(1.0)  # every duplicate has arrived
                return {"refused": refused, "accepted": accepted,
                        "duplicates": link.duplicate_acks, "mode": mock.vehicles[0].mode,
                        "events": [w for _, w in mock.vehicles[0].events]}
            finally:
                await hub.close()

    out = asyncio.run(run())
    assert out["refused"] == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert out["accepted"] == mavlink.MAV_RESULT_ACCEPTED, out
    assert out["mode"] == px4.LAND
    assert out["duplicates"] == 2  # one per command, each counted once and ignored
    assert out["events"] == ["mode AUTO.LOITER -> AUTO.LAND"]  # one change, made once


def test_the_estimate_wanders_and_its_accuracy_is_reported() -> None:
    """On the ground the reported position wanders (GPS-like) and GPS_RAW_INT h_acc / v_acc
    state the estimate's error, which the GCS reads."""

    async def run() -> dict[str, Any]:
        async with MockFleet(1, realism="px4", boot_time=0.0, **mock_ports(1)) as mock:
            hub, link = await _link(mock)
            try:
                assert await link.wait_for(lambda t: not math.isnan(t.gps_h_acc), 5.0)
                seen = []
                for _ in range(20):
                    await asyncio.sleep(0.1)
                    seen.append(link.telemetry.position_ned)
                noise = mock.config.estimate_noise
                assert noise is not None
                return {"h_acc": link.telemetry.gps_h_acc, "v_acc": link.telemetry.gps_v_acc,
                        "seen": seen, "truth": mock.vehicles[0].true_position_world.tolist(),
                        "noise": noise}
            finally:
                await hub.close()

    out = asyncio.run(run())
    assert out["h_acc"] == pytest.approx(out["noise"].horizontal_accuracy, abs=1e-3)
    assert out["v_acc"] == pytest.approx(out["noise"].vertical_accuracy, abs=1e-3)
    assert out["truth"] == [0.0, 0.0, 0.0]  # really on the ground at home
    assert len({p for p in out["seen"]}) > 10  # the reports move
    assert max(abs(p[2]) for p in out["seen"]) > 0.01


def _fly_crossing(position_error: float | None, options: FlightOptions,
                  seed: int) -> dict[str, Any]:
    scenario = QUICK_CROSSING if position_error is None else scenario_for_fleet(
        QUICK_CROSSING, position_error)
    plan = make_plan(scenario)
    assert plan.verification.verified

    async def fly() -> dict[str, Any]:
        homes = homes_under(plan.scenario.starts)
        async with MockFleet(homes=homes, realism="px4", seed=seed, **mock_ports(4),
                             **FAST_MOCK) as mock:
            fleet_dict = mock.fleet_dict(plan.scenario.ids)
            if position_error is not None:
                fleet_dict["position_error"] = position_error
            executor = FlightExecutor(plan, FleetSpec.from_dict(fleet_dict), options)
            started = time.monotonic()
            record = await executor.run()
            record["_seconds"] = time.monotonic() - started
            record["_h_acc"] = mock.config.estimate_noise.horizontal_accuracy  # type: ignore
            return record

    return asyncio.run(fly())


def _goal_errors(record: dict[str, Any]) -> dict[str, float]:
    """The goal errors the executor measured (its "goal_errors" event: "a 0.123 m, ...")."""
    detail = next(e["detail"] for e in record["events"] if e["kind"] == "goal_errors")
    pairs = (item.split() for item in detail.split(", "))
    return {vid: float(value) for vid, value, _unit in pairs}


FAST = FlightOptions(hold_at_goal=1.0, prestream=0.3, climb_speed=2.0)


def _stalled(record: dict[str, Any]) -> bool:
    """Whether the station stalled (a busy machine: the in-process mock stalls with it)."""
    return any(e["kind"] == EventKind.STATION_STALL for e in record["events"])


@pytest.mark.flight
def test_a_crossing_on_px4_like_mocks_completes_with_the_fleets_position_error() -> None:
    """Planned and judged for position_error 0.25 m (as the SITL flight was): it completes,
    each goal judged with max(0.2, 2 x max(0.25, reported h_acc)), tracking error nonzero
    (the estimate wanders, the attitude lags) but bounded."""
    # a wide live tracking bound: a starved station (the in-process mock starves with it)
    # trails the plan by what it lost, which is the paper case's and stall tests' concern;
    # the raw figure is judged below when the station ran throughout
    record = _fly_crossing(0.25, FAST.replace(tracking_error_max=5.0), seed=1)
    s = record["summary"]
    assert s["completed"] is True, s["why"]
    assert s["why"][0].startswith("complete")
    expected = max(0.2, 2.0 * max(0.25, record["_h_acc"]))
    assert s["goal_tolerances"] == {vid: pytest.approx(expected) for vid in "abcd"}
    assert 0.0 < s["goal_error_max"] <= expected
    assert s["faults"] == {}
    assert s["tracking_error_max"] > 0.05, s
    # The summary's figures are measured on the station's clock: a stall of the station
    # (the in-process mock and its vehicles stall with it, then catch up) adds what the
    # station lost to them. The live checks allow for the stall; the figures only hold
    # the plain bounds when the station ran throughout.
    if not _stalled(record):
        assert s["tracking_error_max"] < 1.0, s
        assert s["separation_held"] is True
        assert s["min_separation_measured"] >= s["min_separation_required"]
    assert not [e for e in record["events"] if e["kind"] == EventKind.SEPARATION_ALARM]


@pytest.mark.flight
def test_the_same_crossing_judged_with_a_fixed_tolerance_says_why() -> None:
    """No position_error and a fixed 0.2 m (k = 0): whatever the noise makes of the goals, the
    summary's verdict agrees with the goal errors it reports and states the reasons."""
    # a wide tracking bound: what is judged here is the goal verdict (a stall of the station,
    # which the in-process mock shares, lets the vehicles trail the plan meanwhile)
    # (and only the messages the GCS reads, asked for: half the work of PX4's whole set)
    record = _fly_crossing(None, FAST.replace(goal_tolerance_k=0.0, tracking_error_max=5.0,
                                              message_rates="request"), seed=2)
    s = record["summary"]
    assert s["goal_tolerances"] == {vid: pytest.approx(0.2) for vid in "abcd"}
    errors = _goal_errors(record)
    assert sorted(errors) == list("abcd")
    over = sorted(vid for vid, e in errors.items() if e > 0.2)
    assert s["why"], s
    for vid in over:  # every vehicle over the tolerance is named with its error
        assert any(w.startswith(f"{vid}: {errors[vid]:.2f} m from its goal") for w in s["why"])
    if s["completed"]:
        assert not over and s["why"][0].startswith("complete")
    else:
        assert not s["why"][0].startswith("complete")
        assert over or any("separat" in w or "fault" in w for w in s["why"]), s["why"]


def _fly_side_by_side(offset_m: float) -> dict[str, Any]:
    """Two px4-like vehicles side by side, planned 1.5 m apart for R 1 m + a 0.5 m margin
    (position_error 0.25 m); once the flight clock runs, uav2 holds `offset_m` towards uav1
    off every setpoint (an uncompensated wind), reported as it is."""
    plan = smooth_plan(scenario_for_fleet(short_line(2, spacing=1.5), 0.25))
    assert plan.scenario.min_separation == pytest.approx(1.5)

    async def fly() -> dict[str, Any]:
        homes = homes_under(plan.scenario.starts)
        async with MockFleet(homes=homes, realism="px4", seed=3, **mock_ports(2),
                             **FAST_MOCK) as mock:
            fleet = FleetSpec.from_dict({**mock.fleet_dict(plan.scenario.ids),
                                         "position_error": 0.25})
            executor = FlightExecutor(plan, fleet, FAST.replace(at_end="hold"))

            async def push() -> None:
                await until(lambda: executor.flight_time() is not None,
                            "the flight clock to start", timeout=90.0, poll=0.02)
                # world -x (towards uav1) is LOCAL_NED -y (east)
                mock.vehicles[1].faults.offset_ned = (0.0, -offset_m, 0.0)

            pusher = asyncio.create_task(push())
            try:
                return await executor.run()
            except FlightAborted:  # the alarm: the record says why
                assert executor.record is not None
                return executor.record
            finally:
                pusher.cancel()

    return asyncio.run(fly())


@pytest.mark.flight
@pytest.mark.parametrize(("offset_m", "alarmed"), [(0.2, False), (0.7, True)],
                         ids=["into-the-margin", "below-R"])
def test_the_separation_alarm_lets_a_flight_use_its_margin_and_stops_it_below_r(
        offset_m: float, alarmed: bool) -> None:
    """0.2 m closer (1.3 m apart, and the step's overshoot to about 1.13 m: inside the
    margin, above R, below the 1.2 m that 1.5 m minus a 0.3 m band would give) flies on
    and completes;
    0.7 m closer (about 0.8 m, below R) is stopped by the alarm at R = 1.0 m, not at the
    inflated 1.5 m minus a band."""
    record = _fly_side_by_side(offset_m)
    summary = record["summary"]
    assert summary["separation_alarm_at"] == pytest.approx(1.0)
    alarms = [e for e in record["events"] if e["kind"] == EventKind.SEPARATION_ALARM]
    if alarmed:
        assert alarms and "alarm below 1.00 m" in alarms[0]["detail"], record["events"]
        assert summary["completed"] is False
        assert summary["separation_held"] is False
    else:
        assert alarms == []
        assert summary["completed"] is True, summary["why"]
        assert summary["separation_held"] is True
        assert summary["min_separation_measured"] < 1.2  # it did use the margin
