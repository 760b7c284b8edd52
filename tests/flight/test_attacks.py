"""Attacks by a hostile process on loopback during mock flights (pinned peers,
signing, per-datagram parsing, non-finite telemetry): nothing aborts, diverts or fakes
anything, and the attacker receives nothing."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.run.executor import FlightExecutor
from gcs.sim import MockFleet, homes_under
from gcs.wire import new_key_file
from tests.flight.flying import ALL_ATTACKS, Attacker
from tests.flight.support import FAST_MOCK, line_scenario, mock_ports, smooth_plan
from tests.support.waiting import reached, until

pytestmark = [pytest.mark.timeout(150), pytest.mark.flight]

FAST = FlightOptions(hold_at_goal=1.0, prestream=0.3, climb_speed=2.0)


async def _fly(plan: Any, options: FlightOptions, *, key: Path | None = None,
               attack: str = ALL_ATTACKS, impersonate: list[int] | None = None,
               before_connect: bool = False, during: Any = None,
               autopilots: tuple[str, ...] | None = None) -> tuple[Any, Any, dict]:
    homes = homes_under(plan.scenario.starts)
    secret = None
    if key is not None:
        secret = bytes.fromhex(key.read_text().strip())
    async with MockFleet(homes=homes, settle_time=0.5, signing_key=secret,
                         autopilots=list(autopilots or ["px4"] * len(homes)),
                         **mock_ports(len(homes)),
                         **FAST_MOCK) as mock:
        fleet_dict = mock.fleet_dict(plan.scenario.ids)
        if key is not None:
            fleet_dict["signing_key"] = str(key)
        fleet = FleetSpec.from_dict(fleet_dict)
        ports = [v.gcs_port for v in mock.vehicles]
        attacker = Attacker(ports, impersonate or [v.system_id for v in mock.vehicles], attack)
        flight = FlightExecutor(plan, fleet, options)
        if before_connect:
            await attacker.start()
        task = flight.start()
        if not before_connect:
            # The attacker joins once the vehicles are connected.
            await until(lambda: flight.phase not in ("created", "connecting"),
                        "the vehicles connected", timeout=60.0, poll=0.02)
            await attacker.start()
        if during is not None:
            await during(flight, mock)
        try:
            outcome = await task
        except Exception as exc:
            outcome = exc
        report = await attacker.stop()
        return outcome, mock, report


def _json_clean(record: dict) -> None:
    json.dumps(record, allow_nan=False)  # raises on NaN/Infinity


#: The fleet of the every-attack flight: PX4 and ArduCopter vehicles side by side. Each link
#: is pinned, signed and parsed on its own, by its vehicle's autopilot, so one flight puts
#: both autopilots under every attack.
MIXED = ("px4", "ardupilot", "px4")


@pytest.mark.parametrize("signed", [False, True], ids=["pinned", "signed"])
def test_flight_completes_under_every_attack(signed: bool, tmp_path: Path) -> None:
    """The attacker speaks first, from before the connect: an unsigned vehicle whose first
    contact pinned its peer was pinned to the attacker (its own packets then dropped as
    foreign, the flight failed); the mocks' fleet file names each one's `peer`, as the
    service's does, and a signed link refuses the attacker's unsigned packets. The same on
    PX4 and on ArduCopter, flown together."""
    plan = smooth_plan(line_scenario(3))
    key = new_key_file(tmp_path / "fleet.key").path if signed else None
    record, mock, report = asyncio.run(_fly(plan, FAST, key=key, before_connect=True,
                                            autopilots=MIXED))
    assert isinstance(record, dict), record
    summary = record["summary"]
    assert summary["completed"] is True, summary
    assert summary["faults"] == {}
    assert not [e for e in record["events"] if e["kind"] in ("fault", "abort", "error")]
    # no spoofed mode change ever reached the executor (the spoof says POSCTL)
    modes = {m["mode"] for v in record["vehicles"] for m in v["modes"]}
    assert "POSCTL" not in modes
    # the attacker received nothing, although it sent a lot
    assert report["sent"] > 1000 and report["received"] == 0, report
    # every vehicle's spoofs were dropped and counted, and told live as events; the junk was
    # counted as garbage
    told = {e["vehicle"] for e in record["events"] if e["kind"] == "dropped_packets"}
    assert told == set(plan.scenario.ids)
    for vid in plan.scenario.ids:
        security = summary["security"][vid]
        assert security["foreign_source"] > 0
        assert security["link_garbage_datagrams"] > 0
        assert security["invalid_estimates"] == 0  # the NaN came from the attacker only
    # the real vehicles flew the plan and never fell into a failsafe
    assert tuple(v["autopilot"] for v in record["vehicles"]) == MIXED
    for vehicle, goal in zip(mock.vehicles, plan.scenario.goals, strict=True):
        assert np.linalg.norm(vehicle.position_world[:2] - goal[:2]) < 0.2
        assert not [e for _, e in vehicle.events if "failsafe" in e]
        if signed:
            assert vehicle.signing_key is not None
            assert vehicle.signing.goodsig_count > 100
    _json_clean(record)


def test_spoofed_acks_do_not_hide_a_dead_vehicle() -> None:
    """uav2 goes silent while the attacker sends ACKs, HEARTBEATs and positions as uav2:
    the loss is still caught within the link timeout, and no landing is faked."""
    plan = smooth_plan(line_scenario(3, steps=50))

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await reached(flight, 1.0)
        mock.vehicles[1].faults.silent = True

    options = FAST.replace(policy="land_faulty")
    record, mock, report = asyncio.run(_fly(plan, options, impersonate=[2], during=during))
    assert isinstance(record, dict), record
    flagged = [e for e in record["events"] if e["kind"] == "fault"]
    assert [e["vehicle"] for e in flagged] == ["uav2"] and "link_lost" in flagged[0]["detail"]
    # caught as a silent link (spoofed traffic is no proof of life): the gap it was judged
    # on is the link timeout's, well short of the heartbeat timeout, and the others were
    # still flying the plan then
    gap = float(flagged[0]["detail"].split(" for ")[1].split(" s")[0])
    assert options.link_timeout <= gap < options.heartbeat_timeout  # (detail to 0.01 s)
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index("fault") < kinds.index("horizon")
    # the spoofed ACCEPTED for NAV_LAND was not believed: the landing is unconfirmed
    uav2 = [e for e in record["events"] if e["vehicle"] == "uav2"]
    assert any(e["kind"] == "land_failed" for e in uav2)
    assert not any(e["kind"] == "land" for e in uav2)
    assert record["summary"]["security"]["uav2"]["foreign_source"] > 0
    assert report["received"] == 0
    for i in (0, 2):
        goal = plan.scenario.goals[i]
        assert np.linalg.norm(mock.vehicles[i].position_world[:2] - goal[:2]) < 0.2
    _json_clean(record)


def test_non_finite_position_from_the_vehicle_is_a_fault() -> None:
    """The real uav2 starts reporting NaN: flagged estimate_invalid, handled by the policy;
    no NaN reaches the record or the summary."""
    plan = smooth_plan(line_scenario(3, steps=30))

    async def during(flight: FlightExecutor, mock: MockFleet) -> None:
        await reached(flight, 1.0)
        mock.vehicles[1].faults.nan_position = True

    options = FAST.replace(policy="land_faulty")
    record, mock, _report = asyncio.run(_fly(plan, options, attack="truncated",
                                             during=during))
    assert isinstance(record, dict), record
    summary = record["summary"]
    assert summary["faults"] == {"uav2": "estimate_invalid"}
    assert summary["completed"] is False
    assert summary["security"]["uav2"]["invalid_estimates"] > 0
    assert summary["tracking_error_max"] is not None and np.isfinite(
        summary["tracking_error_max"])
    assert any("AUTO.LAND" in e for _, e in mock.vehicles[1].events)
    for i in (0, 2):
        goal = plan.scenario.goals[i]
        assert np.linalg.norm(mock.vehicles[i].position_world[:2] - goal[:2]) < 0.2
    _json_clean(record)
